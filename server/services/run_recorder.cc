#include "server/services/run_recorder.h"

#include <algorithm>
#include <exception>
#include <utility>

#include "server/protocols/run_outcome.h"
#include "storage/parameter_sets.h"
#include "storage/sessions.h"
#include "storage/trials.h"

namespace fesbench::server::services {

using protocols::RunState;

namespace {

/// The reason of the session revision a tolerance_test run stores (for
/// people reading the session's history; the run's outcome names the
/// revision).
std::string ToleranceRevisionReason(std::int64_t run_id) {
  return "tolerance_test run " + std::to_string(run_id);
}

}  // namespace

// What the end of a run stores and shows, built up by Finish's parts.
struct RunRecorder::FinishRecord {
  api::RunOutcome outcome;  // ConcludeRun's; the set and revision filled when stored
  std::optional<model::ParameterSet> parameter_set;  // the run's fit, to store
  std::vector<int> parameter_set_trials;  // plan trials it was fitted to (empty: all)
  std::optional<int> parameter_set_active_trial;
  std::vector<SafetyEvent> safety_events;
  std::vector<std::optional<std::int64_t>> trial_ids;  // stored id per plan trial
  std::optional<storage::NewParameterSet> new_set;
  std::optional<storage::SessionDetails> measured;  // tolerance_test's limits
  storage::RunBenchTime bench;  // as ran and as planned
  std::optional<storage::Run> stored;  // filled by StoreFinish
};

// --- the runner's observer: the run's thread -----------------------------------------

class RunRecorder::Observer final : public protocols::RunObserver {
 public:
  Observer(RunRecorder& recorder, std::shared_ptr<LiveRun> run)
      : recorder_(recorder), run_(std::move(run)) {}

  void OnStateChanged(RunState state, const std::string& reason) override {
    Guard("state", [&] {
      if (state != RunState::kRunning) return;  // final states: after storing (RecordFinish)
      recorder_.runs_.Locked([&] {
        run_->view.state = state;
        run_->view.started_at = recorder_.db_.Now();
      });
      HubItem item;
      item.kind = HubItem::Kind::kState;
      item.run_id = run_->run_id;
      item.state = state;
      item.reason = reason;
      recorder_.hub_.Publish(std::move(item));
      recorder_.Enqueue(
          [&r = recorder_, run = run_, state, reason] { r.RecordState(*run, state, reason); });
    });
  }

  void OnProgress(const protocols::Progress& progress) override {
    Guard("progress", [&] {
      recorder_.runs_.Locked([&] { run_->view.progress = progress; });
      HubItem item;
      item.kind = HubItem::Kind::kProgress;
      item.run_id = run_->run_id;
      item.progress = progress;
      recorder_.hub_.Publish(std::move(item));
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
      recorder_.hub_.Publish(std::move(item));
    });
  }

  void OnTrial(const protocols::RecordedTrial& trial) override {
    Guard("trial", [&] {
      recorder_.Enqueue([&r = recorder_, run = run_, copy = trial] { r.RecordTrial(*run, copy); });
    });
  }

  void OnFinished(const protocols::RunResult& result) override {
    Guard("finish", [&] {
      protocols::RunResult copy = result;
      copy.trials.clear();  // each was queued by OnTrial
      recorder_.Enqueue(
          [&r = recorder_, run = run_, c = std::move(copy)] { r.RecordFinish(*run, c); });
    });
  }

 private:
  // An observer must never throw into the control loop.
  template <typename F>
  void Guard(const char* what, F&& f) noexcept {
    try {
      f();
    } catch (const std::exception& e) {
      recorder_.log_(std::string("run observer (") + what + "): " + e.what());
    } catch (...) {
      recorder_.log_(std::string("run observer (") + what + "): unknown exception");
    }
  }

  RunRecorder& recorder_;
  std::shared_ptr<LiveRun> run_;
};

// --- the recorder's thread ------------------------------------------------------------

RunRecorder::RunRecorder(storage::Database& db, SampleHub& hub, LiveRuns& runs,
                         protocols::BenchOwner& owner, Log log)
    : db_(db), hub_(hub), runs_(runs), owner_(owner), log_(std::move(log)) {
  thread_ = std::thread([this] { Loop(); });
}

RunRecorder::~RunRecorder() { Stop(); }

std::shared_ptr<protocols::RunObserver> RunRecorder::Observe(std::shared_ptr<LiveRun> run) {
  return std::make_shared<Observer>(*this, std::move(run));
}

void RunRecorder::Refused(std::shared_ptr<LiveRun> run, std::string reason) {
  Enqueue([this, run = std::move(run), reason = std::move(reason)] {
    FinishRecord f;
    f.outcome = protocols::FailOutcome(api::RunOutcome{}, run->stored_state, reason);
    Finish(*run, f);
  });
}

void RunRecorder::Stop() {
  {
    std::lock_guard lock(queue_mu_);
    stopping_ = true;
  }
  queue_cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void RunRecorder::Enqueue(std::function<void()> task) {
  {
    std::lock_guard lock(queue_mu_);
    queue_.push_back(std::move(task));
  }
  queue_cv_.notify_one();
}

void RunRecorder::Loop() {
  for (;;) {
    std::function<void()> task;
    {
      std::unique_lock lock(queue_mu_);
      queue_cv_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping and drained
      task = std::move(queue_.front());
      queue_.pop_front();
    }
    try {
      task();
    } catch (const std::exception& e) {
      log_(std::string("recorder: ") + e.what());
    } catch (...) {
      log_("recorder: unknown exception");
    }
  }
}

void RunRecorder::RecordState(LiveRun& run, RunState state, const std::string& reason) {
  const api::Status st = db_.Write([&](storage::Connection&) -> api::Status {
    api::Result<storage::Run> r =
        storage::SessionRepository(db_).RecordRunState(run.run_id, state, reason);
    if (!r.ok()) return r.status();
    return AppendAudit(db_, run.actor, "run.state", RunTarget(run.run_id),
                       std::string(protocols::RunStateName(state)), "ok");
  });
  if (st.ok()) {
    run.stored_state = state;
  } else {
    log_("storing state of run " + std::to_string(run.run_id) + ": " + st.ToString());
  }
}

void RunRecorder::RecordTrial(LiveRun& run, const protocols::RecordedTrial& trial) {
  const std::string name = trial.trial.name.value_or("trial");
  std::optional<std::int64_t> id;
  // A run stopped before a trial's first sample leaves nothing to store.
  const api::Status st =
      trial.trial.num_samples() == 0
          ? api::Status::Ok()
          : db_.Write([&](storage::Connection&) -> api::Status {
              api::Result<std::int64_t> inserted = storage::TrialRepository(db_).Insert(
                  storage::TrialOwner{run.view.session_id, run.run_id}, trial.trial);
              if (!inserted.ok()) return inserted.status();
              const std::size_t samples = trial.trial.num_samples();
              api::Status a = AppendAudit(
                  db_, run.actor, "trial.record", "trials/" + std::to_string(*inserted),
                  RunTarget(run.run_id) + " trial " + name + ", " + std::to_string(samples) +
                      " samples" + (trial.complete ? "" : " (incomplete)"),
                  "ok");
              if (!a.ok()) return a;
              id = *inserted;
              return api::Status::Ok();
            });
  if (!st.ok()) {
    id.reset();
    log_("storing trial " + name + " of run " + std::to_string(run.run_id) + ": " + st.ToString());
  }
  const int index = runs_.Locked([&] {
    run.trial_ids.push_back(id);
    if (id) run.view.trial_ids.push_back(*id);
    return static_cast<int>(run.trial_ids.size()) - 1;
  });
  HubItem item;
  item.kind = HubItem::Kind::kTrial;
  item.run_id = run.run_id;
  item.samples.trial = index;
  item.samples.trial_name = name;
  item.trial_id = id;
  hub_.Publish(std::move(item));
}

// --- the end of a run -----------------------------------------------------------------

void RunRecorder::RecordFinish(LiveRun& run, const protocols::RunResult& result) {
  FinishRecord f;
  protocols::RunConclusionInput input;
  input.protocol = result.protocol;
  input.parameters = runs_.Locked([&] { return run.view.parameters; });
  input.leg_parameter_set_id = run.prior_parameter_set_id;
  f.outcome = protocols::ConcludeRun(input, result);
  f.parameter_set = result.parameter_set;
  f.parameter_set_trials = result.parameter_set_trials;
  f.parameter_set_active_trial = result.parameter_set_active_trial;
  f.safety_events = result.safety_events;
  Finish(run, f);
}

void RunRecorder::Finish(LiveRun& run, FinishRecord& f) {
  runs_.Locked([&] {
    f.trial_ids = run.trial_ids;
    // The final progress (the time run) came before the result.
    f.bench = {run.view.progress.bench_total_s, run.view.progress.bench_planned_s};
  });
  PrepareParameterSet(run, f);
  PrepareMeasuredLimits(run, f);
  StoreFinish(run, f);
  // The view turns final only once the bench is free again, so that a
  // caller who saw the end may start the next run at once.
  if (run.on_bench.load()) (void)owner_.Wait();
  PublishFinish(run, f);
}

void RunRecorder::PrepareParameterSet(const LiveRun& run, FinishRecord& f) const {
  if (f.outcome.state != RunState::kDone || !f.parameter_set) return;
  const auto stored_id = [&](int index) -> std::optional<std::int64_t> {
    if (index < 0 || static_cast<std::size_t>(index) >= f.trial_ids.size()) return std::nullopt;
    return f.trial_ids[static_cast<std::size_t>(index)];
  };
  // The rapid protocol's set, its provenance naming the stored trials it
  // was fitted to (§7.4.1: ramp IRC, the holds before the releases, the
  // free swings, random binary).
  storage::NewParameterSet ns;
  ns.subject_id = run.subject_id;
  ns.leg_id = run.leg_id;
  ns.params = *f.parameter_set;
  ns.supersedes_id = run.prior_parameter_set_id;
  ns.run_id = run.run_id;
  std::vector<std::int64_t> ids;
  const std::vector<int>& fitted = f.parameter_set_trials;  // the rapid set's
  if (!fitted.empty()) {
    for (int k : fitted) {
      if (auto id = stored_id(k)) ids.push_back(*id);
    }
    if (f.parameter_set_active_trial) {
      ns.params.provenance.active_trial_id = stored_id(*f.parameter_set_active_trial);
    }
  } else {
    for (const auto& id : f.trial_ids) {
      if (id) ids.push_back(*id);
    }
  }
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  ns.params.provenance.trial_ids = ids;
  if (!fitted.empty() && ids.size() != fitted.size()) {
    f.outcome = protocols::FailOutcome(
        std::move(f.outcome), run.stored_state,
        "the run's trials could not all be stored; its parameter set is not stored");
    return;
  }
  f.new_set = std::move(ns);
}

namespace {

void Warn(api::RunOutcome& outcome, std::string warning) {
  if (outcome.tolerance && outcome.tolerance->test) {
    outcome.tolerance->test->warnings.push_back(std::move(warning));
  }
}

}  // namespace

void RunRecorder::PrepareMeasuredLimits(const LiveRun& run, FinishRecord& f) {
  // tolerance_test writes what it measured into the session (docs/PROTOCOLS.md,
  // `tolerance_test`): a session revision by the run's user, so that the protocols that need
  // threshold and max tolerated may run at once. A ramp that ended at its
  // ceiling measured no max (ConcludeRun said so).
  const std::optional<api::ToleranceOutcome>& t = f.outcome.tolerance;
  if (f.outcome.state != RunState::kDone || !t || t->ended_at_ceiling || !t->threshold_ma) return;
  api::Result<storage::Session> session = storage::SessionRepository(db_).Get(run.view.session_id);
  if (!session.ok()) {
    Warn(f.outcome, "the session could not be read: " + session.status().message());
    return;
  }
  storage::SessionDetails d = session->current.details;
  d.threshold_ma = t->threshold_ma;
  d.max_tolerated_ma = t->max_tolerated_ma;
  if (api::Status valid = storage::ValidateSessionDetails(d); !valid.ok()) {
    Warn(f.outcome, "the measured values were not stored in the session: " + valid.message());
    return;
  }
  f.measured = std::move(d);
}

api::Status RunRecorder::WriteFinish(const LiveRun& run, FinishRecord& f, bool with_results) {
  return db_.Write([&](storage::Connection&) -> api::Status {
    f.outcome.parameter_set_id.reset();
    f.outcome.session_revision.reset();
    std::string summary = std::string(protocols::RunStateName(f.outcome.state));
    if (!f.outcome.reason.empty()) summary += ": " + f.outcome.reason;
    if (with_results && f.measured) {
      api::Result<storage::Session> corrected = storage::SessionRepository(db_).Correct(
          run.view.session_id, *f.measured, ToleranceRevisionReason(run.run_id),
          run.actor.user_name);
      if (!corrected.ok()) return corrected.status();
      f.outcome.session_revision = corrected->current.revision;
      summary += "; session " + std::to_string(run.view.session_id) + " revision " +
                 std::to_string(corrected->current.revision) + " (threshold " +
                 FormatNumber(*f.measured->threshold_ma) + " mA, max tolerated " +
                 FormatNumber(*f.measured->max_tolerated_ma) + " mA)";
    }
    if (with_results && f.new_set) {
      api::Result<storage::ParameterSetSummary> ins =
          storage::ParameterSetRepository(db_).Insert(*f.new_set);
      if (!ins.ok()) return ins.status();
      f.outcome.parameter_set_id = ins->id;
      summary += "; parameter set " + std::to_string(ins->id);
      if (api::Status st = ApproveRunSet(run, ins->id); !st.ok()) return st;
    }
    api::Result<storage::Run> r = storage::SessionRepository(db_).RecordRunState(
        run.run_id, f.outcome.state, f.outcome.reason, f.bench, &f.outcome);
    if (!r.ok()) return r.status();
    f.stored = *r;
    return AppendAudit(db_, run.actor, "run.finish", RunTarget(run.run_id), summary, "ok");
  });
}

// docs/SAFETY.md, which set gates stimulation: a set a bench run measured
// is the operating clinician's own measurement, approved by the run that
// stored it (audited with the run), in the transaction that stores it.
api::Status RunRecorder::ApproveRunSet(const LiveRun& run, std::int64_t set_id) {
  if (!May(run.actor, Permission::kApprove)) return api::Status::Ok();  // a candidate, as any other
  storage::NewApproval approval;
  approval.parameter_set_id = set_id;
  if (run.actor.user_id > 0) approval.approved_by_user_id = run.actor.user_id;
  approval.approved_by = run.actor.user_name.empty() ? std::string("unknown") : run.actor.user_name;
  approval.run_id = run.run_id;
  approval.note = "identified by run " + std::to_string(run.run_id) + " (" + run.view.protocol +
                  ") on the bench";
  api::Result<storage::Approval> approved = storage::ParameterSetRepository(db_).Approve(approval);
  if (!approved.ok()) return approved.status();
  return AppendAudit(db_, run.actor, "parameter_set.approve", "parameter-sets/" + std::to_string(set_id),
               "approved by run " + std::to_string(run.run_id) + ": " + approval.note, "ok");
}

void RunRecorder::StoreFinish(const LiveRun& run, FinishRecord& f) {
  api::Status st = WriteFinish(run, f, true);
  if (!st.ok() && f.measured) {
    log_("storing the measured limits of run " + std::to_string(run.run_id) + ": " + st.ToString());
    Warn(f.outcome, "the measured values could not be stored in the session: " + st.message());
    f.measured.reset();
    st = WriteFinish(run, f, true);
  }
  if (!st.ok() && f.new_set) {
    log_("storing the parameter set of run " + std::to_string(run.run_id) + ": " + st.ToString());
    f.outcome = protocols::FailOutcome(std::move(f.outcome), run.stored_state,
                                       "storing the parameter set failed: " + st.message());
    st = WriteFinish(run, f, false);
  }
  if (!st.ok()) {
    log_("storing the end of run " + std::to_string(run.run_id) + ": " + st.ToString());
  }
}

void RunRecorder::PublishFinish(LiveRun& run, const FinishRecord& f) {
  HubItem item;
  item.kind = HubItem::Kind::kEnd;
  item.run_id = run.run_id;
  item.state = f.outcome.state;
  item.reason = f.outcome.reason;
  item.parameter_set_id = f.outcome.parameter_set_id;
  runs_.Finalise(run, [&](api::RunView& v) {
    api::ShowOutcome(f.outcome, v);
    v.finished_at = f.stored && f.stored->finished_at ? f.stored->finished_at : db_.Now();
    if (f.stored && f.stored->started_at) v.started_at = f.stored->started_at;
    v.safety_events = f.safety_events;
    if (f.outcome.state == RunState::kDone) {
      v.progress.fraction = 1.0;
      v.progress.eta_s = 0.0;
    }
    item.result = v.result;
  });
  hub_.Publish(std::move(item));
}

}  // namespace fesbench::server::services
