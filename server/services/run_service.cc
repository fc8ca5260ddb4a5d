#include "server/services/run_service.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <iostream>
#include <set>
#include <sstream>
#include <utility>

#include "model/tracking.h"
#include "server/protocols/rapid_identification.h"
#include "server/protocols/run_json.h"
#include "storage/audit_log.h"
#include "storage/estop_latch.h"
#include "storage/parameter_sets.h"
#include "storage/subjects.h"
#include "storage/trials.h"

namespace fesbench::server::services {

using protocols::RunState;

namespace {

nlohmann::json OptionalTime(const std::optional<storage::UtcTime>& t) {
  return t ? nlohmann::json(storage::FormatUtc(*t)) : nlohmann::json(nullptr);
}

template <typename T>
nlohmann::json OptionalValue(const std::optional<T>& v) {
  return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
}

std::string RunTarget(std::int64_t run_id) { return "runs/" + std::to_string(run_id); }

/// The reason of the session revision a tolerance_test run stores; also how
/// a stored run finds its revision again.
std::string ToleranceRevisionReason(std::int64_t run_id) {
  return "tolerance_test run " + std::to_string(run_id);
}

nlohmann::json ToleranceResultJson(const storage::SessionDetails& d, int revision) {
  return {{"threshold_ma", d.threshold_ma ? nlohmann::json(*d.threshold_ma) : nlohmann::json()},
          {"max_tolerated_ma",
           d.max_tolerated_ma ? nlohmann::json(*d.max_tolerated_ma) : nlohmann::json()},
          {"session_revision", revision}};
}

std::string FormatNumber(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

// --- JSON -----------------------------------------------------------------------

nlohmann::json RunViewToJson(const RunView& v) {
  nlohmann::json parameters = nlohmann::json::object();
  for (const auto& [k, x] : v.parameters) parameters[k] = x;
  nlohmann::json values = nlohmann::json::object();
  for (const auto& [k, x] : v.values) {
    values[k] = std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr);
  }
  nlohmann::json events = nlohmann::json::array();
  for (const SafetyEvent& e : v.safety_events) events.push_back(protocols::SafetyEventToJson(e));
  const double eta = v.progress.eta_s;
  nlohmann::json j = {
      {"run_id", v.run_id},
      {"session_id", v.session_id},
      {"protocol", v.protocol},
      {"protocol_version", v.protocol_version},
      {"parameters", std::move(parameters)},
      {"state", std::string(protocols::RunStateName(v.state))},
      {"reason", v.reason},
      {"progress", v.progress.fraction},
      {"eta_s", std::isfinite(eta) && eta >= 0.0 ? nlohmann::json(eta) : nlohmann::json(nullptr)},
      {"created_at_utc", storage::FormatUtc(v.created_at)},
      {"started_at_utc", OptionalTime(v.started_at)},
      {"finished_at_utc", OptionalTime(v.finished_at)},
      {"result", v.result},
      {"controller", v.owner.empty() ? nlohmann::json(nullptr) : nlohmann::json(v.owner)},
      {"bench_elapsed_s", v.progress.bench_elapsed_s},
      {"bench_total_s", v.progress.bench_total_s},
      {"trial_ids", v.trial_ids},
      {"parameter_set_id", OptionalValue(v.parameter_set_id)},
      {"values", std::move(values)},
      {"safety_events", std::move(events)},
      {"live", v.live}};
  if (v.tolerance) {
    protocols::RunResult r;
    r.tolerance = v.tolerance;
    j["tolerance"] = protocols::RunResultToJson(r).at("tolerance");
  }
  return j;
}

nlohmann::json BenchStateToJson(const BenchState& s) {
  return {{"kind", s.kind},
          {"mode", s.mode},
          {"busy", s.busy},
          {"estopped", s.estopped},
          {"estop_source", s.estop_source},
          {"owner", s.owner},
          {"owner_user_id", OptionalValue(s.owner_user_id)},
          {"run_id", OptionalValue(s.run_id)},
          {"protocol", s.protocol},
          {"run_state", std::string(protocols::RunStateName(s.run_state))},
          {"progress", protocols::ProgressToJson(s.progress)}};
}

// --- session context ----------------------------------------------------------------

api::Result<SessionContext> LoadSessionContext(storage::Database& db, std::int64_t session_id,
                                               const BenchLimits& limits) {
  api::Result<storage::Session> session = storage::SessionRepository(db).Get(session_id);
  if (!session.ok()) return session.status();
  api::Result<storage::Subject> subject = storage::SubjectRepository(db).Get(session->subject_id);
  if (!subject.ok()) return subject.status();

  SessionContext out;
  out.session = *session;
  protocols::SubjectContext& c = out.subject;
  const storage::SessionDetails& d = session->current.details;
  out.has_stimulation_limits = d.threshold_ma.has_value() && d.max_tolerated_ma.has_value();
  // Without recorded limits only tolerance_test may run (it measures them):
  // without a recorded max, the stimulator's range, which the test's
  // ceiling_ma bounds; with one, the recorded max bounds the test too.
  c.threshold_ma = d.threshold_ma.value_or(0.0);
  c.max_tolerated_recorded = d.max_tolerated_ma.has_value();
  c.max_tolerated_ma = c.max_tolerated_recorded ? *d.max_tolerated_ma : limits.max_stim_ma;
  // Storage keeps no range of motion: the bench's mechanical range (DESIGN.md §2).
  c.min_angle_deg = limits.min_angle_deg;
  c.max_angle_deg = limits.max_angle_deg;
  // Eq. 4.13, §4.2.1: body mass and the femoral condyle–medial malleolus
  // length (the shank length) give the inertia when no prior set does.
  const storage::SubjectDetails& a = subject->current.details;
  if (a.weight_kg) c.body_mass_kg = *a.weight_kg;
  if (a.shank_length_cm) c.leg_length_m = *a.shank_length_cm / 100.0;

  api::Result<storage::StoredParameterSet> latest =
      storage::ParameterSetRepository(db).Latest(session->subject_id, session->leg_id);
  if (latest.ok()) {
    c.parameter_set = latest->params;
    c.parameter_set_id = latest->summary.id;
    out.parameter_set_id = latest->summary.id;
    // The leg's history, newest first (daily_check's drift bounds).
    storage::ParameterSetRepository sets(db);
    storage::HistoryQuery q;
    q.subject_id = session->subject_id;
    q.leg_id = session->leg_id;
    api::Result<std::vector<storage::ParameterSetSummary>> history = sets.History(q);
    if (!history.ok()) return history.status();
    for (auto it = history->rbegin(); it != history->rend() && c.history.size() < 20; ++it) {
      api::Result<storage::StoredParameterSet> s = sets.Get(it->id);
      if (s.ok()) c.history.push_back(s->params);
    }
    storage::TrialRepository trials(db);
    for (std::int64_t id : latest->trial_ids) {
      api::Result<api::Trial> t = trials.Get(id);
      if (!t.ok()) continue;
      const std::string name = t->name.value_or("");
      if (name == "rapid_isometric_ramp_irc" || name == "daily_check_ramp_irc") {
        c.base_ramp_trial = api::ToTrialColumns(*t);
        break;
      }
    }
  } else if (latest.status().code() != api::ErrorCode::kNotFound) {
    return latest.status();
  }
  return out;
}

// --- the live run ---------------------------------------------------------------------

struct RunService::LiveRun {
  // Fixed at start.
  std::int64_t run_id = 0;
  std::int64_t subject_id = 0;
  std::int64_t leg_id = 0;
  Actor actor;
  protocols::BenchMode mode = protocols::BenchMode::kLocked;
  std::optional<protocols::RapidSettings> rapid;
  std::optional<std::int64_t> prior_parameter_set_id;
  // Guarded by RunService::mu_.
  RunView view;
  std::vector<std::optional<std::int64_t>> trial_ids;  // by trial index
  bool final = false;
  /// Handed to the BenchOwner: its end waits for the bench to be released.
  std::atomic<bool> on_bench{false};
  // Run thread only.
  std::uint64_t next_sample = 0;
};

/// The runner's observer: runs on the run's thread, so it only updates the
/// in-memory view, copies into the hub and queues storage work.
class RunService::Observer final : public protocols::RunObserver {
 public:
  Observer(RunService& service, std::shared_ptr<LiveRun> run)
      : service_(service), run_(std::move(run)) {}

  void OnStateChanged(RunState state, const std::string& reason) override {
    Guard("state", [&] {
      if (state != RunState::kRunning) return;  // final states: after storing (RecordFinish)
      {
        std::lock_guard lock(service_.mu_);
        run_->view.state = state;
        run_->view.started_at = service_.db_.Now();
      }
      HubItem item;
      item.kind = HubItem::Kind::kState;
      item.run_id = run_->run_id;
      item.state = state;
      item.reason = reason;
      service_.hub_.Publish(std::move(item));
      service_.Enqueue(
          [&s = service_, run = run_, state, reason] { s.RecordState(run, state, reason); });
    });
  }

  void OnProgress(const protocols::Progress& progress) override {
    Guard("progress", [&] {
      {
        std::lock_guard lock(service_.mu_);
        run_->view.progress = progress;
      }
      HubItem item;
      item.kind = HubItem::Kind::kProgress;
      item.run_id = run_->run_id;
      item.progress = progress;
      service_.hub_.Publish(std::move(item));
    });
  }

  void OnSamples(const protocols::SampleBatch& batch) override {
    Guard("samples", [&] {
      HubItem item;
      item.kind = HubItem::Kind::kSamples;
      item.run_id = run_->run_id;
      item.first_sample = run_->next_sample;
      item.samples = batch;
      run_->next_sample += batch.t_s.size();
      service_.hub_.Publish(std::move(item));
    });
  }

  void OnTrial(const protocols::RecordedTrial& trial) override {
    Guard("trial", [&] {
      service_.Enqueue([&s = service_, run = run_, copy = trial] { s.RecordTrial(run, copy); });
    });
  }

  void OnFinished(const protocols::RunResult& result) override {
    Guard("finish", [&] {
      protocols::RunResult copy;  // everything but the trials (already queued)
      copy.state = result.state;
      copy.reason = result.reason;
      copy.protocol = result.protocol;
      copy.protocol_version = result.protocol_version;
      copy.parameters = result.parameters;
      copy.parameter_set = result.parameter_set;
      copy.tolerance = result.tolerance;
      copy.daily_check = result.daily_check;
      copy.safety_events = result.safety_events;
      copy.values = result.values;
      copy.bench_duration_s = result.bench_duration_s;
      copy.wall_duration_s = result.wall_duration_s;
      service_.Enqueue(
          [&s = service_, run = run_, r = std::move(copy)] { s.RecordFinish(run, r); });
    });
  }

 private:
  // An observer must never throw into the control loop.
  template <typename F>
  void Guard(const char* what, F&& f) noexcept {
    try {
      f();
    } catch (const std::exception& e) {
      service_.Log(std::string("run observer (") + what + "): " + e.what());
    } catch (...) {
      service_.Log(std::string("run observer (") + what + "): unknown exception");
    }
  }

  RunService& service_;
  std::shared_ptr<LiveRun> run_;
};

// --- construction and the recorder ------------------------------------------------

namespace {

protocols::BenchOwnerOptions OwnerOptions(const RunServiceConfig& c) {
  protocols::BenchOwnerOptions o;
  o.runner.time_scale = c.time_scale;
  o.runner.progress_interval_s = c.progress_interval_s;
  o.runner.batch_samples = std::max<std::size_t>(1, c.batch_samples);
  o.runner.arm_watchdog = c.arm_watchdog;
  o.runner.heartbeat_timeout_s = c.heartbeat_timeout_s;
  o.runner.wall_clock = c.wall_clock;
  o.wall_clock = c.wall_clock;
  return o;
}

}  // namespace

RunService::RunService(storage::Database& db, Bench& bench, SampleHub& hub, RunServiceConfig config)
    : db_(db),
      bench_(bench),
      hub_(hub),
      config_(std::move(config)),
      owner_(bench, OwnerOptions(config_)) {
  recorder_ = std::thread([this] { RecorderLoop(); });
}

RunService::~RunService() { Shutdown(); }

void RunService::Log(std::string_view message) const {
  if (config_.log) {
    config_.log(message);
  } else {
    std::cerr << "fesbench-server: run service: " << message << std::endl;
  }
}

void RunService::Enqueue(std::function<void()> task) {
  {
    std::lock_guard lock(queue_mu_);
    queue_.push_back(std::move(task));
  }
  queue_cv_.notify_one();
}

void RunService::RecorderLoop() {
  for (;;) {
    std::function<void()> task;
    {
      std::unique_lock lock(queue_mu_);
      queue_cv_.wait(lock, [&] { return queue_stop_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping and drained
      task = std::move(queue_.front());
      queue_.pop_front();
    }
    try {
      task();
    } catch (const std::exception& e) {
      Log(std::string("recorder: ") + e.what());
    } catch (...) {
      Log("recorder: unknown exception");
    }
  }
}

api::Status RunService::Audit(const Actor& actor, const std::string& action,
                              const std::string& target, const std::string& summary,
                              const std::string& outcome) {
  storage::NewAuditEntry e;
  if (actor.user_id > 0) e.user_id = actor.user_id;
  e.actor = actor.user_name.empty() ? std::string("unknown") : actor.user_name;
  e.action = action;
  e.target = target;
  e.request_summary = summary;
  e.outcome = outcome;
  api::Result<std::int64_t> id = storage::AuditLog(db_).Append(e);
  return id.ok() ? api::Status::Ok() : id.status();
}

void RunService::RecordState(const std::shared_ptr<LiveRun>& run, RunState state,
                             const std::string& reason) {
  const api::Status st = db_.Write([&](storage::Connection&) -> api::Status {
    api::Result<storage::Run> r =
        storage::SessionRepository(db_).RecordRunState(run->run_id, state, reason);
    if (!r.ok()) return r.status();
    return Audit(run->actor, "run.state", RunTarget(run->run_id),
                 std::string(protocols::RunStateName(state)), "ok");
  });
  if (!st.ok()) Log("storing state of run " + std::to_string(run->run_id) + ": " + st.ToString());
}

void RunService::RecordTrial(const std::shared_ptr<LiveRun>& run,
                             const protocols::RecordedTrial& trial) {
  const std::string name = trial.trial.name.value_or("trial");
  std::optional<std::int64_t> id;
  // A run stopped before a trial's first sample leaves nothing to store.
  const api::Status st =
      trial.trial.num_samples() == 0
          ? api::Status::Ok()
          : db_.Write([&](storage::Connection&) -> api::Status {
              api::Result<std::int64_t> inserted = storage::TrialRepository(db_).Insert(
                  storage::TrialOwner{run->view.session_id, run->run_id}, trial.trial);
              if (!inserted.ok()) return inserted.status();
              const std::size_t samples = trial.trial.num_samples();
              api::Status a =
                  Audit(run->actor, "trial.record", "trials/" + std::to_string(*inserted),
                        RunTarget(run->run_id) + " trial " + name + ", " + std::to_string(samples) +
                            " samples" + (trial.complete ? "" : " (incomplete)"),
                        "ok");
              if (!a.ok()) return a;
              id = *inserted;
              return api::Status::Ok();
            });
  if (!st.ok()) {
    id.reset();
    Log("storing trial " + name + " of run " + std::to_string(run->run_id) + ": " + st.ToString());
  }
  int index = -1;
  {
    std::lock_guard lock(mu_);
    run->trial_ids.push_back(id);
    index = static_cast<int>(run->trial_ids.size()) - 1;
    if (id) run->view.trial_ids.push_back(*id);
  }
  HubItem item;
  item.kind = HubItem::Kind::kTrial;
  item.run_id = run->run_id;
  item.samples.trial = index;
  item.samples.trial_name = name;
  item.trial_id = id;
  hub_.Publish(std::move(item));
}

void RunService::RecordFinish(const std::shared_ptr<LiveRun>& run,
                              const protocols::RunResult& result) {
  RunState state = result.state;
  std::string reason = result.reason;
  if (!protocols::IsFinal(state)) {
    state = RunState::kFailed;
    reason = "the run ended in state " + std::string(protocols::RunStateName(result.state));
  }
  std::vector<std::optional<std::int64_t>> trial_ids;
  {
    std::lock_guard lock(mu_);
    trial_ids = run->trial_ids;
  }
  const auto stored_id = [&](int index) -> std::optional<std::int64_t> {
    if (index < 0 || static_cast<std::size_t>(index) >= trial_ids.size()) return std::nullopt;
    return trial_ids[static_cast<std::size_t>(index)];
  };

  // The rapid protocol's set, its provenance naming the stored trials it
  // was fitted to (§7.4.1: ramp IRC, the holds before the releases, the
  // free swings, random binary).
  std::optional<storage::NewParameterSet> new_set;
  if (state == RunState::kDone && result.parameter_set) {
    storage::NewParameterSet ns;
    ns.subject_id = run->subject_id;
    ns.leg_id = run->leg_id;
    ns.params = *result.parameter_set;
    ns.supersedes_id = run->prior_parameter_set_id;
    ns.run_id = run->run_id;
    std::vector<std::int64_t> ids;
    std::size_t expected = 0;  // trials the rapid set was fitted to
    if (run->rapid) {
      std::vector<int> fitted = {run->rapid->ramp_trial, run->rapid->passive_trial,
                                 run->rapid->active_trial};
      fitted.insert(fitted.end(), run->rapid->swing_trials.begin(), run->rapid->swing_trials.end());
      for (const auto& [hold, swing] : run->rapid->release_trials) fitted.push_back(hold);
      std::sort(fitted.begin(), fitted.end());
      fitted.erase(std::unique(fitted.begin(), fitted.end()), fitted.end());
      expected = fitted.size();
      for (int k : fitted) {
        if (auto id = stored_id(k)) ids.push_back(*id);
      }
      ns.params.provenance.active_trial_id = stored_id(run->rapid->active_trial);
    } else {
      for (const auto& id : trial_ids) {
        if (id) ids.push_back(*id);
      }
    }
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    ns.params.provenance.trial_ids = ids;
    new_set = std::move(ns);
    if (ids.size() != expected && run->rapid) {
      state = RunState::kFailed;
      reason = "the run's trials could not all be stored; its parameter set is not stored";
      new_set.reset();
    }
  }

  // tolerance_test writes what it measured into the session (issue 14):
  // a session revision by the run's user, so that the protocols that need
  // threshold and max tolerated may run at once.
  std::optional<storage::SessionDetails> measured;
  std::vector<std::string> warnings;
  if (state == RunState::kDone && result.tolerance) {
    const protocols::ToleranceResult& t = *result.tolerance;
    if (!t.threshold_ma) {
      warnings.push_back(
          "no threshold was detected: the session's threshold and max tolerated are unchanged");
    } else {
      api::Result<storage::Session> session =
          storage::SessionRepository(db_).Get(run->view.session_id);
      if (session.ok()) {
        storage::SessionDetails d = session->current.details;
        d.threshold_ma = *t.threshold_ma;
        d.max_tolerated_ma = t.max_tolerated_ma;
        if (api::Status valid = storage::ValidateSessionDetails(d); valid.ok()) {
          measured = std::move(d);
        } else {
          warnings.push_back("the measured values were not stored in the session: " +
                             valid.message());
        }
      } else {
        warnings.push_back("the session could not be read: " + session.status().message());
      }
    }
  }

  std::optional<std::int64_t> set_id;
  std::optional<int> session_revision;
  std::optional<storage::Run> stored;
  const auto write = [&](RunState s, const std::string& why, bool with_set) -> api::Status {
    return db_.Write([&](storage::Connection&) -> api::Status {
      set_id.reset();
      session_revision.reset();
      std::string summary = std::string(protocols::RunStateName(s));
      if (!why.empty()) summary += ": " + why;
      if (with_set && measured) {
        api::Result<storage::Session> corrected = storage::SessionRepository(db_).Correct(
            run->view.session_id, *measured, ToleranceRevisionReason(run->run_id),
            run->actor.user_name);
        if (!corrected.ok()) return corrected.status();
        session_revision = corrected->current.revision;
        summary += "; session " + std::to_string(run->view.session_id) + " revision " +
                   std::to_string(*session_revision) + " (threshold " +
                   FormatNumber(*measured->threshold_ma) + " mA, max tolerated " +
                   FormatNumber(*measured->max_tolerated_ma) + " mA)";
      }
      if (with_set && new_set) {
        api::Result<storage::ParameterSetSummary> ins =
            storage::ParameterSetRepository(db_).Insert(*new_set);
        if (!ins.ok()) return ins.status();
        set_id = ins->id;
        summary += "; parameter set " + std::to_string(ins->id);
      }
      api::Result<storage::Run> r =
          storage::SessionRepository(db_).RecordRunState(run->run_id, s, why);
      if (!r.ok()) return r.status();
      stored = *r;
      return Audit(run->actor, "run.finish", RunTarget(run->run_id), summary, "ok");
    });
  };
  api::Status st = write(state, reason, true);
  if (!st.ok() && measured) {
    Log("storing the measured limits of run " + std::to_string(run->run_id) + ": " + st.ToString());
    warnings.push_back("the measured values could not be stored in the session: " + st.message());
    measured.reset();
    st = write(state, reason, true);
  }
  if (!st.ok() && new_set) {
    Log("storing the parameter set of run " + std::to_string(run->run_id) + ": " + st.ToString());
    state = RunState::kFailed;
    reason = "storing the parameter set failed: " + st.message();
    st = write(state, reason, false);
  }
  if (!st.ok()) {
    Log("storing the end of run " + std::to_string(run->run_id) + ": " + st.ToString());
  }

  // The view turns final only once the bench is free again, so that a
  // caller who saw the end may start the next run at once.
  if (run->on_bench.load()) (void)owner_.Wait();
  {
    std::lock_guard lock(mu_);
    RunView& v = run->view;
    v.state = state;
    v.reason = reason;
    v.finished_at = stored && stored->finished_at ? stored->finished_at : db_.Now();
    if (stored && stored->started_at) v.started_at = stored->started_at;
    v.parameter_set_id = set_id;
    v.safety_events = result.safety_events;
    v.tolerance = result.tolerance;
    if (v.tolerance) {
      for (std::string& w : warnings) v.tolerance->warnings.push_back(std::move(w));
    }
    v.values = result.values;
    if (session_revision && measured) {
      v.result = ToleranceResultJson(*measured, *session_revision);
    } else if (state == RunState::kDone && result.tolerance) {
      storage::SessionDetails d;  // measured, but not stored in the session
      d.threshold_ma = result.tolerance->threshold_ma;
      d.max_tolerated_ma = result.tolerance->max_tolerated_ma;
      v.result = ToleranceResultJson(d, 0);
      v.result["session_revision"] = nullptr;
    } else if (state == RunState::kDone && result.daily_check) {
      v.result = *result.daily_check;
      v.result["parameter_set_id"] = set_id ? nlohmann::json(*set_id) : nlohmann::json(nullptr);
    } else if (set_id) {
      v.result = {{"parameter_set_id", *set_id}};
    }
    if (state == RunState::kDone) {
      v.progress.fraction = 1.0;
      v.progress.eta_s = 0.0;
    }
    run->final = true;
  }
  final_cv_.notify_all();

  HubItem item;
  item.kind = HubItem::Kind::kEnd;
  item.run_id = run->run_id;
  item.state = state;
  item.reason = reason;
  item.parameter_set_id = set_id;
  {
    std::lock_guard lock(mu_);
    item.result = run->view.result;
  }
  hub_.Publish(std::move(item));
  Forget();
}

void RunService::Forget() {
  std::lock_guard lock(mu_);
  std::size_t finished = 0;
  for (const auto& [id, r] : runs_) finished += r->final ? 1 : 0;
  for (auto it = runs_.begin(); it != runs_.end() && finished > config_.finished_runs_kept;) {
    if (it->second->final && it->first != current_run_id_) {
      it = runs_.erase(it);
      --finished;
    } else {
      ++it;
    }
  }
}

// --- queries ------------------------------------------------------------------------

std::shared_ptr<RunService::LiveRun> RunService::FindLive(std::int64_t run_id) const {
  std::lock_guard lock(mu_);
  const auto it = runs_.find(run_id);
  return it == runs_.end() ? nullptr : it->second;
}

std::shared_ptr<RunService::LiveRun> RunService::Current() const {
  std::lock_guard lock(mu_);
  const auto it = runs_.find(current_run_id_);
  return it == runs_.end() ? nullptr : it->second;
}

api::Result<RunView> RunService::StoredView(std::int64_t run_id) {
  api::Result<storage::Run> run = storage::SessionRepository(db_).GetRun(run_id);
  if (!run.ok()) return run.status();
  RunView v;
  v.run_id = run->id;
  v.session_id = run->session_id;
  v.protocol = run->protocol_name;
  try {
    v.protocol_version = std::stoi(run->protocol_version);
  } catch (const std::exception&) {
    v.protocol_version = 0;
  }
  const nlohmann::json params = nlohmann::json::parse(run->parameters_json, nullptr, false);
  if (params.is_object()) {
    for (const auto& [k, x] : params.items()) {
      if (x.is_number()) v.parameters[k] = x.get<double>();
    }
  }
  v.state = run->state;
  if (v.state == RunState::kFailed || v.state == RunState::kAborted) v.reason = run->message;
  v.created_at = run->created_at;
  v.started_at = run->started_at;
  v.finished_at = run->finished_at;
  if (v.state == RunState::kDone) v.progress.fraction = 1.0;

  api::Result<std::vector<std::int64_t>> trial_ids = storage::TrialRepository(db_).IdsOfRun(run_id);
  if (!trial_ids.ok()) return trial_ids.status();
  v.trial_ids = std::move(*trial_ids);
  if (v.state == RunState::kDone && v.protocol == "tolerance_test") {
    api::Result<std::vector<storage::SessionRevision>> revisions =
        storage::SessionRepository(db_).Revisions(run->session_id);
    if (!revisions.ok()) return revisions.status();
    const std::string reason = ToleranceRevisionReason(run_id);
    for (const storage::SessionRevision& r : *revisions) {
      if (r.reason == reason) v.result = ToleranceResultJson(r.details, r.revision);
    }
  }
  // The set a completed run stored names the run (migration 13); a set
  // stored before that is found by its provenance naming the run's trials.
  if (v.state == RunState::kDone) {
    api::Result<std::optional<std::int64_t>> by_run =
        storage::ParameterSetRepository(db_).IdForRun(run_id);
    if (!by_run.ok()) return by_run.status();
    if (*by_run) {
      v.parameter_set_id = **by_run;
      v.result = {{"parameter_set_id", **by_run}};
      return v;
    }
  }
  const bool may_have_set = v.protocol == "rapid_parameterisation" || v.protocol == "daily_check";
  if (v.state == RunState::kDone && may_have_set && !v.trial_ids.empty()) {
    api::Result<storage::Session> session = storage::SessionRepository(db_).Get(run->session_id);
    if (!session.ok()) return session.status();
    storage::HistoryQuery q;
    q.subject_id = session->subject_id;
    q.leg_id = session->leg_id;
    q.from = run->created_at;
    api::Result<std::vector<storage::ParameterSetSummary>> history =
        storage::ParameterSetRepository(db_).History(q);
    if (!history.ok()) return history.status();
    const std::set<std::int64_t> mine(v.trial_ids.begin(), v.trial_ids.end());
    for (const storage::ParameterSetSummary& s : *history) {
      api::Result<storage::StoredParameterSet> set = storage::ParameterSetRepository(db_).Get(s.id);
      if (!set.ok()) continue;
      const bool all_mine = !set->trial_ids.empty() &&
                            std::all_of(set->trial_ids.begin(), set->trial_ids.end(),
                                        [&](std::int64_t id) { return mine.count(id) > 0; });
      if (all_mine) {
        v.parameter_set_id = s.id;
        v.result = {{"parameter_set_id", s.id}};
        break;
      }
    }
  }
  return v;
}

api::Result<RunView> RunService::Get(std::int64_t run_id) {
  try {
    if (auto run = FindLive(run_id)) {
      std::lock_guard lock(mu_);
      return run->view;
    }
    return StoredView(run_id);
  } catch (const std::exception& e) {
    Log(std::string("Get: ") + e.what());
    return api::Status::Internal("reading the run failed");
  }
}

api::Result<RunView> RunService::Wait(std::int64_t run_id, std::chrono::milliseconds timeout) {
  try {
    if (auto run = FindLive(run_id)) {
      std::unique_lock lock(mu_);
      final_cv_.wait_for(lock, timeout, [&] { return run->final; });
      return run->view;
    }
    return StoredView(run_id);
  } catch (const std::exception& e) {
    Log(std::string("Wait: ") + e.what());
    return api::Status::Internal("reading the run failed");
  }
}

BenchState RunService::State() const {
  BenchState s;
  s.kind = std::string(bench_.kind());
  s.estopped = const_cast<protocols::BenchOwner&>(owner_).safe_bench().estopped() ||
               bench_.HardwareEStopped();
  s.busy = owner_.busy();
  std::lock_guard lock(mu_);
  if (s.estopped) s.estop_source = estop_source_;
  const auto it = runs_.find(current_run_id_);
  if (it == runs_.end()) return s;
  const LiveRun& r = *it->second;
  s.run_id = r.run_id;
  s.protocol = r.view.protocol;
  s.run_state = r.view.state;
  s.progress = r.view.progress;
  if (!r.final) {
    s.busy = true;  // still storing what it produced
    s.mode = std::string(protocols::BenchModeName(r.mode));
    s.owner = r.actor.user_name;
    s.owner_user_id = r.actor.user_id;
  }
  return s;
}

// --- commands ----------------------------------------------------------------------

api::Result<RunView> RunService::Start(const Actor& actor, std::int64_t session_id,
                                       const std::string& protocol,
                                       const protocols::ParameterValues& parameters,
                                       const std::optional<std::string>& ceiling_reason,
                                       const TargetSamples* target) {
  try {
    return StartImpl(actor, session_id, protocol, parameters, ceiling_reason, target);
  } catch (const std::exception& e) {
    Log(std::string("Start: ") + e.what());
    return api::Status::Internal("starting the run failed");
  }
}

api::Result<RunView> RunService::StartImpl(const Actor& actor, std::int64_t session_id,
                                           const std::string& protocol,
                                           const protocols::ParameterValues& parameters,
                                           const std::optional<std::string>& ceiling_reason,
                                           const TargetSamples* target) {
  if (!MayOperateBench(actor)) {
    return api::Status(api::ErrorCode::kPermissionDenied,
                       "starting a run needs the clinician or admin role");
  }
  const protocols::ProtocolDescription* description = protocols::FindProtocol(protocol);
  if (description == nullptr) return api::Status::NotFound("unknown protocol '" + protocol + "'");
  for (const auto& [name, value] : parameters) {
    if (!std::isfinite(value)) {
      return api::Status::InvalidArgument("must be finite", "parameters." + name);
    }
  }

  std::lock_guard start_lock(start_mu_);
  {
    std::lock_guard lock(mu_);
    if (shutting_down_) return api::Status::Unavailable("the server is shutting down");
  }
  api::Result<SessionContext> context = LoadSessionContext(db_, session_id, bench_.limits());
  if (!context.ok()) return context.status();
  if (!context->has_stimulation_limits &&
      description->kind != protocols::ProtocolKind::kTolerance) {
    return api::Status::FailedPrecondition(
        "session " + std::to_string(session_id) +
        " has no threshold and max tolerated amplitude: record them (tolerance_test) first");
  }
  if (owner_.busy()) {
    return api::Status::Conflict("the bench is held by a run of " + owner_.owner());
  }
  if (const std::shared_ptr<LiveRun> previous = Current()) {
    std::lock_guard lock(mu_);
    if (!previous->final) return api::Status::Conflict("the previous run is still being stored");
  }
  if (owner_.safe_bench().estopped() || bench_.HardwareEStopped()) {
    return api::Status::Conflict("e-stop latched: clear it first");
  }

  protocols::StartRequest request;
  request.protocol = protocol;
  request.parameters = parameters;
  request.subject = context->subject;
  request.subject.ceiling_above_max = ceiling_reason;
  request.client = actor.user_name;
  // The stimulator's limit bounds every ceiling, explicit or not.
  if (const auto it = parameters.find("ceiling_ma");
      it != parameters.end() && it->second > bench_.limits().max_stim_ma) {
    return api::Status::InvalidArgument(
        "above the stimulator's limit " + FormatNumber(bench_.limits().max_stim_ma) + " mA",
        "parameters.ceiling_ma");
  }
  // tracking's uploaded target, at the control's 200 Hz.
  if (target != nullptr) {
    try {
      request.target_angle_deg = model::ResampleTarget(target->t_s, target->angle_deg, 200.0);
    } catch (const std::invalid_argument& e) {
      return api::Status::InvalidArgument(e.what(), "target_samples");
    }
    if (request.target_angle_deg.size() > 600 * 200 + 1) {
      return api::Status::InvalidArgument("longer than 600 s", "target_samples");
    }
  }
  // A tracking run may name the leg's set to invert (0: its newest).
  if (const auto it = parameters.find("parameter_set_id");
      it != parameters.end() && it->second >= 1.0 && std::isfinite(it->second)) {
    const auto id = static_cast<std::int64_t>(it->second);
    api::Result<storage::StoredParameterSet> chosen = storage::ParameterSetRepository(db_).Get(id);
    if (!chosen.ok()) {
      if (chosen.status().code() != api::ErrorCode::kNotFound) return chosen.status();
      return api::Status::InvalidArgument("no parameter set " + std::to_string(id),
                                          "parameters.parameter_set_id");
    }
    if (chosen->summary.subject_id != context->session.subject_id ||
        chosen->summary.leg_id != context->session.leg_id) {
      return api::Status::InvalidArgument(
          "parameter set " + std::to_string(id) + " belongs to another subject or leg",
          "parameters.parameter_set_id");
    }
    request.subject.parameter_set = chosen->params;
    request.subject.parameter_set_id = id;
  }
  api::Result<protocols::Plan> plan = owner_.Prepare(request);
  if (!plan.ok()) return plan.status();
  if (plan->rapid) {
    // An explicit inertia (parameter inertia_kgm2 > 0) comes before any other source.
    if (const auto it = plan->parameters.find("inertia_kgm2");
        it != plan->parameters.end() && it->second > 0.0) {
      request.subject.inertia_kgm2 = it->second;
    }
    api::Result<double> inertia = protocols::KnownInertia(request.subject);
    if (!inertia.ok()) return inertia.status();
  }

  nlohmann::json params_json = nlohmann::json::object();
  for (const auto& [k, v] : plan->parameters) params_json[k] = v;
  storage::NewRun new_run;
  new_run.protocol_name = protocol;
  new_run.protocol_version = std::to_string(plan->protocol_version);
  new_run.parameters_json = params_json.dump();
  api::Result<storage::Run> created =
      db_.Write([&](storage::Connection&) -> api::Result<storage::Run> {
        api::Result<storage::Run> r =
            storage::SessionRepository(db_).CreateRun(session_id, new_run);
        if (!r.ok()) return r;
        std::string summary = "session " + std::to_string(session_id) + ", " + protocol + " v" +
                              new_run.protocol_version;
        for (const auto& [k, v] : parameters) summary += ", " + k + "=" + FormatNumber(v);
        if (api::Status a = Audit(actor, "run.start", RunTarget(r->id), summary, "ok"); !a.ok()) {
          return a;
        }
        if (ceiling_reason) {
          const std::string why =
              "tolerance test ceiling " + FormatNumber(plan->parameters.at("ceiling_ma")) +
              " mA above the session's recorded max tolerated " +
              FormatNumber(context->subject.max_tolerated_ma) + " mA; reason: " + *ceiling_reason;
          if (api::Status a = Audit(actor, "run.ceiling_above_max", RunTarget(r->id), why, "ok");
              !a.ok()) {
            return a;
          }
        }
        return r;
      });
  if (!created.ok()) return created.status();

  auto run = std::make_shared<LiveRun>();
  run->run_id = created->id;
  run->subject_id = context->session.subject_id;
  run->leg_id = context->session.leg_id;
  run->actor = actor;
  run->mode = description->bench_mode;
  run->rapid = plan->rapid;
  run->prior_parameter_set_id = context->parameter_set_id;
  RunView& v = run->view;
  v.run_id = created->id;
  v.session_id = session_id;
  v.protocol = protocol;
  v.protocol_version = plan->protocol_version;
  v.parameters = plan->parameters;
  v.state = RunState::kQueued;
  v.owner = actor.user_name;
  v.owner_user_id = actor.user_id;
  v.created_at = created->created_at;
  v.progress.bench_total_s = plan->duration_s();
  v.progress.eta_s = config_.time_scale > 0.0 ? plan->duration_s() / config_.time_scale : 0.0;
  v.live = true;
  {
    std::lock_guard lock(mu_);
    runs_[run->run_id] = run;
    current_run_id_ = run->run_id;
  }
  HubItem queued;
  queued.kind = HubItem::Kind::kState;
  queued.run_id = run->run_id;
  queued.state = RunState::kQueued;
  queued.progress = v.progress;
  hub_.Publish(std::move(queued));

  run->on_bench = true;
  api::Status started = owner_.Start(request, std::make_shared<Observer>(*this, run));
  if (!started.ok()) {
    run->on_bench = false;
    // Refused at the last moment (e.g. an e-stop in between): the run failed.
    Enqueue([this, run, started] {
      protocols::RunResult r;
      r.state = RunState::kFailed;
      r.reason = started.message();
      RecordFinish(run, r);
    });
    return started;
  }
  std::lock_guard lock(mu_);
  return run->view;
}

api::Status RunService::CheckCurrent(std::int64_t run_id, std::shared_ptr<LiveRun>* out) {
  std::shared_ptr<LiveRun> run = FindLive(run_id);
  if (!run) {
    api::Result<storage::Run> stored = storage::SessionRepository(db_).GetRun(run_id);
    if (!stored.ok()) return stored.status();
    const std::string& bench = db_.options().bench_id;
    if (!stored->bench_id.empty() && stored->bench_id != bench && !api::IsFinal(stored->state)) {
      return api::Status::Conflict("run " + std::to_string(run_id) + " runs on bench '" +
                                   stored->bench_id + "', not on this server's bench '" + bench +
                                   "': send this to that bench's server");
    }
    return api::Status::Conflict("run " + std::to_string(run_id) + " is not in progress (" +
                                 std::string(api::RunStateName(stored->state)) + ")");
  }
  std::lock_guard lock(mu_);
  if (run->final || run_id != current_run_id_) {
    return api::Status::Conflict("run " + std::to_string(run_id) + " is not in progress (" +
                                 std::string(protocols::RunStateName(run->view.state)) + ")");
  }
  *out = std::move(run);
  return api::Status::Ok();
}

api::Status RunService::Cancel(const Actor& actor, std::int64_t run_id) {
  try {
    if (!MayOperateBench(actor)) {
      return api::Status(api::ErrorCode::kPermissionDenied,
                         "cancelling a run needs the clinician or admin role");
    }
    std::shared_ptr<LiveRun> run;
    if (api::Status st = CheckCurrent(run_id, &run); !st.ok()) return st;
    if (api::Status st = owner_.Cancel("cancelled by " + actor.user_name); !st.ok()) {
      return api::Status::Conflict("run " + std::to_string(run_id) + " is no longer running");
    }
    if (api::Status a = Audit(actor, "run.cancel", RunTarget(run_id), "cancel", "ok"); !a.ok()) {
      Log("audit of cancel: " + a.ToString());
    }
    return api::Status::Ok();
  } catch (const std::exception& e) {
    Log(std::string("Cancel: ") + e.what());
    return api::Status::Internal("cancelling the run failed");
  }
}

api::Status RunService::StopWithResult(const Actor& actor, std::int64_t run_id) {
  try {
    if (!MayOperateBench(actor)) {
      return api::Status(api::ErrorCode::kPermissionDenied,
                         "stopping a run needs the clinician or admin role");
    }
    std::shared_ptr<LiveRun> run;
    if (api::Status st = CheckCurrent(run_id, &run); !st.ok()) return st;
    if (api::Status st = owner_.Stop(); !st.ok()) {
      return api::Status::Conflict("run " + std::to_string(run_id) + " is no longer running");
    }
    if (api::Status a = Audit(actor, "run.stop", RunTarget(run_id), "stop with result", "ok");
        !a.ok()) {
      Log("audit of stop: " + a.ToString());
    }
    return api::Status::Ok();
  } catch (const std::exception& e) {
    Log(std::string("StopWithResult: ") + e.what());
    return api::Status::Internal("stopping the run failed");
  }
}

api::Status RunService::Heartbeat(const Actor& actor, std::int64_t run_id) {
  try {
    std::shared_ptr<LiveRun> run;
    if (api::Status st = CheckCurrent(run_id, &run); !st.ok()) return st;
    if (run->actor.user_id != actor.user_id || run->actor.user_name != actor.user_name) {
      return api::Status(api::ErrorCode::kPermissionDenied,
                         "only " + run->actor.user_name + ", who started run " +
                             std::to_string(run_id) + ", controls it");
    }
    owner_.Heartbeat();
    return api::Status::Ok();
  } catch (const std::exception& e) {
    Log(std::string("Heartbeat: ") + e.what());
    return api::Status::Internal("heartbeat failed");
  }
}

api::Status RunService::EStop(const Actor& actor, std::string_view source) {
  const std::string who =
      (source.empty() ? std::string("unknown source") : std::string(source)) + " (" +
      (actor.user_name.empty() ? std::string("unknown") : actor.user_name) + ")";
  // Act first: nothing may delay the e-stop (DESIGN.md §6).
  owner_.EStop(who);
  try {
    {
      std::lock_guard lock(mu_);
      estop_source_ = who;
    }
    const std::shared_ptr<LiveRun> run = Current();
    const std::string target = run && !run->final ? RunTarget(run->run_id) : std::string("bench");
    // The latch outlives this process: stored with its audit row, before the answer.
    const api::Status stored = db_.Write([&](storage::Connection&) -> api::Status {
      if (api::Status st = storage::EStopLatchRepository(db_).RecordLatched(who, actor.user_name);
          !st.ok()) {
        return st;
      }
      return Audit(actor, "bench.estop", target, "e-stop from " + who, "ok");
    });
    if (!stored.ok()) Log("storing the e-stop latch: " + stored.ToString());
  } catch (const std::exception& e) {
    Log(std::string("EStop (after latching): ") + e.what());
  }
  return api::Status::Ok();
}

api::Status RunService::ClearEStop(const Actor& actor) {
  try {
    if (!MayOperateBench(actor)) {
      return api::Status(api::ErrorCode::kPermissionDenied,
                         "clearing the e-stop needs the clinician or admin role");
    }
    if (owner_.busy()) {
      return api::Status::Conflict("a run is still stopping; clear the e-stop after it ends");
    }
    // While latched no run can start, so the bench stays idle from here on.
    const bool was = owner_.safe_bench().estopped() || bench_.HardwareEStopped();
    // Stored and audited first, in one transaction: if that fails the latch
    // stays set in both places and the person can try again.
    const api::Status stored = db_.Write([&](storage::Connection&) -> api::Status {
      storage::EStopLatchRepository latch(db_);
      api::Result<std::optional<storage::LatchedEStop>> current = latch.Current();
      if (!current.ok()) return current.status();
      if (*current || was) {
        if (api::Status st = latch.RecordCleared(actor.user_name); !st.ok()) return st;
      }
      return Audit(actor, "bench.clear_estop", "bench",
                   *current || was ? "e-stop cleared" : "e-stop was not latched", "ok");
    });
    if (!stored.ok()) return stored;
    if (api::Status st = owner_.ClearEStop("cleared by " + actor.user_name); !st.ok()) return st;
    // A hardware e-stop (the bench button) is cleared with it.
    if (bench_.HardwareEStopped()) bench_.ClearHardwareEStop();
    {
      std::lock_guard lock(mu_);
      estop_source_.clear();
    }
    return api::Status::Ok();
  } catch (const std::exception& e) {
    Log(std::string("ClearEStop: ") + e.what());
    return api::Status::Internal("clearing the e-stop failed");
  }
}

api::Result<Recovery> RunService::RecoverAfterRestart() {
  const Actor system = SystemActor();
  Recovery out;
  api::Result<std::vector<storage::Run>> unfinished =
      storage::SessionRepository(db_).ListUnfinishedRuns();
  if (!unfinished.ok()) return unfinished.status();
  for (const storage::Run& run : *unfinished) {
    if (FindLive(run.id)) continue;  // never ours: called before any start
    const api::Status closed = db_.Write([&](storage::Connection&) -> api::Status {
      api::Result<storage::Run> r = storage::SessionRepository(db_).RecordRunState(
          run.id, RunState::kFailed, kStoppedDuringRunReason);
      if (!r.ok()) return r.status();
      return Audit(system, "run.recovered", RunTarget(run.id),
                   std::string("was ") + std::string(api::RunStateName(run.state)) + ": " +
                       kStoppedDuringRunReason,
                   "ok");
    });
    if (!closed.ok()) return closed;
    out.failed_run_ids.push_back(run.id);
  }

  api::Result<std::optional<storage::LatchedEStop>> latched =
      storage::EStopLatchRepository(db_).Current();
  if (!latched.ok()) return latched.status();
  if (*latched) {
    const std::string who =
        (*latched)->source.empty() ? std::string("e-stop before the restart") : (*latched)->source;
    owner_.EStop(who);
    {
      std::lock_guard lock(mu_);
      estop_source_ = who;
    }
    if (api::Status a = Audit(system, "bench.estop_restored", "bench",
                              "e-stop latched since " + storage::FormatUtc((*latched)->at) +
                                  " by " + who + ": latched again at start",
                              "ok");
        !a.ok()) {
      return a;
    }
    out.estop_source = who;
  }
  return out;
}

api::Status RunService::WithIdleBench(const std::function<api::Status()>& fn) {
  try {
    std::lock_guard start_lock(start_mu_);
    {
      std::lock_guard lock(mu_);
      if (shutting_down_) return api::Status::Unavailable("the server is shutting down");
    }
    if (owner_.busy()) {
      return api::Status::Conflict("a run of " + owner_.owner() + " holds the bench");
    }
    return fn();
  } catch (const std::exception& e) {
    Log(std::string("WithIdleBench: ") + e.what());
    return api::Status::Internal("changing the bench failed");
  }
}

void RunService::Shutdown() {
  std::lock_guard start_lock(start_mu_);
  {
    std::lock_guard lock(mu_);
    shutting_down_ = true;
  }
  try {
    if (owner_.busy()) (void)owner_.Cancel("server shutting down");
    (void)owner_.Wait();  // stimulation is 0 once the runner returns
  } catch (const std::exception& e) {
    Log(std::string("Shutdown: ") + e.what());
  }
  {
    std::lock_guard lock(queue_mu_);
    queue_stop_ = true;
  }
  queue_cv_.notify_all();
  if (recorder_.joinable()) recorder_.join();
}

}  // namespace fesbench::server::services
