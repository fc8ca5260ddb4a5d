#include "server/services/run_service_internal.h"

// RunService's recorder: what a run produces goes to storage on the
// recorder thread (states, trials, the end with its set and session limits).

namespace fesbench::server::services {

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

// What the end of a run stores and shows, built up by RecordFinish's parts.
struct RunService::FinishRecord {
  RunState state = RunState::kFailed;
  std::string reason;
  std::vector<std::optional<std::int64_t>> trial_ids;  // stored id per plan trial
  std::optional<storage::NewParameterSet> new_set;
  std::optional<storage::SessionDetails> measured;  // tolerance_test's limits
  // Set when a tolerance test ended at its ceiling: why no max is recorded.
  std::optional<std::string> max_not_recorded;
  std::vector<std::string> warnings;
  storage::RunBenchTime bench;  // as ran and as planned
  // Filled by StoreFinish.
  std::optional<std::int64_t> set_id;
  std::optional<int> session_revision;
  std::optional<storage::Run> stored;
};

void RunService::RecordFinish(const std::shared_ptr<LiveRun>& run,
                              const protocols::RunResult& result) {
  FinishRecord f;
  f.state = result.state;
  f.reason = result.reason;
  if (!protocols::IsFinal(f.state)) {
    f.state = RunState::kFailed;
    f.reason = "the run ended in state " + std::string(protocols::RunStateName(result.state));
  }
  {
    std::lock_guard lock(mu_);
    f.trial_ids = run->trial_ids;
    // The final progress (the time run) came before the result.
    f.bench = {run->view.progress.bench_total_s, run->view.progress.bench_planned_s};
  }
  PrepareParameterSet(*run, result, f);
  PrepareMeasuredLimits(*run, result, f);
  StoreFinish(*run, f);
  // The view turns final only once the bench is free again, so that a
  // caller who saw the end may start the next run at once.
  if (run->on_bench.load()) (void)owner_.Wait();
  PublishFinish(run, result, f);
  Forget();
}

void RunService::PrepareParameterSet(const LiveRun& run, const protocols::RunResult& result,
                                     FinishRecord& f) const {
  if (f.state != RunState::kDone || !result.parameter_set) return;
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
  ns.params = *result.parameter_set;
  ns.supersedes_id = run.prior_parameter_set_id;
  ns.run_id = run.run_id;
  std::vector<std::int64_t> ids;
  std::size_t expected = 0;  // trials the rapid set was fitted to
  if (run.rapid) {
    std::vector<int> fitted = {run.rapid->ramp_trial, run.rapid->passive_trial,
                               run.rapid->active_trial};
    fitted.insert(fitted.end(), run.rapid->swing_trials.begin(), run.rapid->swing_trials.end());
    for (const auto& [hold, swing] : run.rapid->release_trials) fitted.push_back(hold);
    std::sort(fitted.begin(), fitted.end());
    fitted.erase(std::unique(fitted.begin(), fitted.end()), fitted.end());
    expected = fitted.size();
    for (int k : fitted) {
      if (auto id = stored_id(k)) ids.push_back(*id);
    }
    ns.params.provenance.active_trial_id = stored_id(run.rapid->active_trial);
  } else {
    for (const auto& id : f.trial_ids) {
      if (id) ids.push_back(*id);
    }
  }
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  ns.params.provenance.trial_ids = ids;
  if (ids.size() != expected && run.rapid) {
    f.state = RunState::kFailed;
    f.reason = "the run's trials could not all be stored; its parameter set is not stored";
    return;
  }
  f.new_set = std::move(ns);
}

namespace {

// docs/SAFETY.md, tolerance test ceiling: the ramp reaching its ceiling
// says only that the subject bore the ceiling, not where their limit is.
// Only a limit the subject signalled or the clinician stopped at is a
// measured max tolerated amplitude.
bool EndedAtCeiling(const protocols::RunResult& result) {
  const auto signalled = result.values.find("subject_signalled_limit");
  return result.tolerance && !result.tolerance->stopped_by_clinician &&
         (signalled == result.values.end() || signalled->second != 1.0);
}

std::string CeilingMessage(const RunView& view) {
  const auto ceiling = view.parameters.find("ceiling_ma");
  const std::string at = ceiling == view.parameters.end()
                             ? std::string("its ceiling")
                             : "its ceiling of " + FormatNumber(ceiling->second) + " mA";
  return "the ramp reached " + at +
         " without the subject signalling the limit or a clinician stopping it: no max "
         "tolerated amplitude was measured, and the session's threshold and max tolerated are "
         "unchanged; re-test (stop the ramp where the subject says so), or enter the max "
         "tolerated amplitude as a clinician (a correction of the session)";
}

}  // namespace

void RunService::PrepareMeasuredLimits(const LiveRun& run, const protocols::RunResult& result,
                                       FinishRecord& f) {
  // tolerance_test writes what it measured into the session (docs/PROTOCOLS.md,
  // `tolerance_test`): a session revision by the run's user, so that the protocols that need
  // threshold and max tolerated may run at once.
  if (f.state != RunState::kDone || !result.tolerance) return;
  const protocols::ToleranceResult& t = *result.tolerance;
  if (EndedAtCeiling(result)) {
    f.max_not_recorded = CeilingMessage(run.view);
    f.warnings.push_back(*f.max_not_recorded);
    return;
  }
  if (!t.threshold_ma) {
    f.warnings.push_back(
        "no threshold was detected: the session's threshold and max tolerated are unchanged");
    return;
  }
  api::Result<storage::Session> session = storage::SessionRepository(db_).Get(run.view.session_id);
  if (!session.ok()) {
    f.warnings.push_back("the session could not be read: " + session.status().message());
    return;
  }
  storage::SessionDetails d = session->current.details;
  d.threshold_ma = *t.threshold_ma;
  d.max_tolerated_ma = t.max_tolerated_ma;
  if (api::Status valid = storage::ValidateSessionDetails(d); !valid.ok()) {
    f.warnings.push_back("the measured values were not stored in the session: " +
                         valid.message());
    return;
  }
  f.measured = std::move(d);
}

api::Status RunService::WriteFinish(const LiveRun& run, FinishRecord& f, bool with_results) {
  return db_.Write([&](storage::Connection&) -> api::Status {
    f.set_id.reset();
    f.session_revision.reset();
    std::string summary = std::string(protocols::RunStateName(f.state));
    if (!f.reason.empty()) summary += ": " + f.reason;
    if (with_results && f.measured) {
      api::Result<storage::Session> corrected = storage::SessionRepository(db_).Correct(
          run.view.session_id, *f.measured, ToleranceRevisionReason(run.run_id),
          run.actor.user_name);
      if (!corrected.ok()) return corrected.status();
      f.session_revision = corrected->current.revision;
      summary += "; session " + std::to_string(run.view.session_id) + " revision " +
                 std::to_string(*f.session_revision) + " (threshold " +
                 FormatNumber(*f.measured->threshold_ma) + " mA, max tolerated " +
                 FormatNumber(*f.measured->max_tolerated_ma) + " mA)";
    }
    if (with_results && f.new_set) {
      api::Result<storage::ParameterSetSummary> ins =
          storage::ParameterSetRepository(db_).Insert(*f.new_set);
      if (!ins.ok()) return ins.status();
      f.set_id = ins->id;
      summary += "; parameter set " + std::to_string(ins->id);
      if (api::Status st = ApproveRunSet(run, ins->id); !st.ok()) return st;
    }
    api::Result<storage::Run> r =
        storage::SessionRepository(db_).RecordRunState(run.run_id, f.state, f.reason, f.bench);
    if (!r.ok()) return r.status();
    f.stored = *r;
    return Audit(run.actor, "run.finish", RunTarget(run.run_id), summary, "ok");
  });
}

// docs/SAFETY.md, which set gates stimulation: a set a bench run measured
// is the operating clinician's own measurement, approved by the run that
// stored it (audited with the run), in the transaction that stores it.
api::Status RunService::ApproveRunSet(const LiveRun& run, std::int64_t set_id) {
  if (!MayOperateBench(run.actor)) return api::Status::Ok();  // a candidate, as any other
  storage::NewApproval approval;
  approval.parameter_set_id = set_id;
  if (run.actor.user_id > 0) approval.approved_by_user_id = run.actor.user_id;
  approval.approved_by = run.actor.user_name.empty() ? std::string("unknown") : run.actor.user_name;
  approval.run_id = run.run_id;
  approval.note = "identified by run " + std::to_string(run.run_id) + " (" + run.view.protocol +
                  ") on the bench";
  api::Result<storage::Approval> approved = storage::ParameterSetRepository(db_).Approve(approval);
  if (!approved.ok()) return approved.status();
  return Audit(run.actor, "parameter_set.approve", "parameter-sets/" + std::to_string(set_id),
               "approved by run " + std::to_string(run.run_id) + ": " + approval.note, "ok");
}

void RunService::StoreFinish(const LiveRun& run, FinishRecord& f) {
  api::Status st = WriteFinish(run, f, true);
  if (!st.ok() && f.measured) {
    Log("storing the measured limits of run " + std::to_string(run.run_id) + ": " + st.ToString());
    f.warnings.push_back("the measured values could not be stored in the session: " +
                         st.message());
    f.measured.reset();
    st = WriteFinish(run, f, true);
  }
  if (!st.ok() && f.new_set) {
    Log("storing the parameter set of run " + std::to_string(run.run_id) + ": " + st.ToString());
    f.state = RunState::kFailed;
    f.reason = "storing the parameter set failed: " + st.message();
    st = WriteFinish(run, f, false);
  }
  if (!st.ok()) {
    Log("storing the end of run " + std::to_string(run.run_id) + ": " + st.ToString());
  }
}

void RunService::PublishFinish(const std::shared_ptr<LiveRun>& run,
                               const protocols::RunResult& result, FinishRecord& f) {
  {
    std::lock_guard lock(mu_);
    RunView& v = run->view;
    v.state = f.state;
    v.reason = f.reason;
    v.finished_at = f.stored && f.stored->finished_at ? f.stored->finished_at : db_.Now();
    if (f.stored && f.stored->started_at) v.started_at = f.stored->started_at;
    v.parameter_set_id = f.set_id;
    v.safety_events = result.safety_events;
    v.tolerance = result.tolerance;
    if (v.tolerance) {
      for (std::string& w : f.warnings) v.tolerance->warnings.push_back(std::move(w));
    }
    v.values = result.values;
    if (f.session_revision && f.measured) {
      v.result = ToleranceResultJson(*f.measured, *f.session_revision, v.values);
    } else if (f.state == RunState::kDone && result.tolerance) {
      storage::SessionDetails d;  // measured, but not stored in the session
      d.threshold_ma = result.tolerance->threshold_ma;
      if (!f.max_not_recorded) d.max_tolerated_ma = result.tolerance->max_tolerated_ma;
      v.result = ToleranceResultJson(d, 0, v.values);
      v.result["session_revision"] = nullptr;
      if (f.max_not_recorded) {
        v.result["ended_at_ceiling"] = true;
        v.result["message"] = *f.max_not_recorded;
      }
    } else if (f.state == RunState::kDone && result.daily_check) {
      v.result = *result.daily_check;
      v.result["parameter_set_id"] = f.set_id ? nlohmann::json(*f.set_id) : nlohmann::json(nullptr);
    } else if (f.set_id) {
      v.result = {{"parameter_set_id", *f.set_id}};
    }
    if (f.state == RunState::kDone) {
      v.progress.fraction = 1.0;
      v.progress.eta_s = 0.0;
    }
    run->final = true;
  }
  final_cv_.notify_all();

  HubItem item;
  item.kind = HubItem::Kind::kEnd;
  item.run_id = run->run_id;
  item.state = f.state;
  item.reason = f.reason;
  item.parameter_set_id = f.set_id;
  {
    std::lock_guard lock(mu_);
    item.result = run->view.result;
  }
  hub_.Publish(std::move(item));
}

}  // namespace fesbench::server::services
