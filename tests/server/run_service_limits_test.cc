// RunService's refusals and limits: unknown ids and bad input get the right
// codes, a session without limits runs only the tolerance test, the tolerance
// test stays under the recorded max, recovery after a restart, and the
// session context a run starts from.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "server/protocols/plan.h"
#include "server/services/run_service.h"
#include "storage/audit_log.h"
#include "storage/estop_latch.h"
#include "storage/parameter_sets.h"
#include "storage/subjects.h"
#include "storage/trials.h"
#include "storage/users.h"
#include "tests/server/run_service_rig.h"

namespace fesbench::server::services {
namespace {

using namespace std::chrono_literals;
using protocols::RunState;
using namespace test;  // the rig (run_service_rig.h)

// --- refusals ------------------------------------------------------------------------------

TEST(RunService, UnknownIdsAndBadInputAreRefusedWithTheRightCode) {
  Rig rig;
  auto code = [](const auto& r) { return r.status().code(); };
  EXPECT_EQ(code(rig.service->Get(999)), api::ErrorCode::kNotFound);
  EXPECT_EQ(code(rig.service->Wait(999, 0ms)), api::ErrorCode::kNotFound);
  EXPECT_EQ(rig.service->Cancel(rig.clinician, 999).code(), api::ErrorCode::kNotFound);
  EXPECT_EQ(rig.service->StopWithResult(rig.clinician, 999).code(), api::ErrorCode::kNotFound);
  EXPECT_EQ(rig.service->Heartbeat(rig.clinician, 999).code(), api::ErrorCode::kNotFound);
  EXPECT_EQ(code(rig.service->Start(rig.clinician, 999, "isometric_ramp_irc", {})),
            api::ErrorCode::kNotFound);
  EXPECT_EQ(code(rig.service->Start(rig.clinician, rig.session_id, "no_such_protocol", {})),
            api::ErrorCode::kNotFound);
  EXPECT_EQ(code(rig.service->Start(rig.analyst, rig.session_id, "isometric_ramp_irc", {})),
            api::ErrorCode::kPermissionDenied);

  auto bad =
      rig.service->Start(rig.clinician, rig.session_id, "isometric_ramp_irc", {{"ramps", 2.5}});
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(bad.status().field(), "parameters.ramps");
  auto unknown =
      rig.service->Start(rig.clinician, rig.session_id, "isometric_ramp_irc", {{"colour", 1.0}});
  EXPECT_EQ(unknown.status().field(), "parameters.colour");
  auto nan = rig.service->Start(rig.clinician, rig.session_id, "isometric_ramp_irc",
                                {{"ramps", std::nan("")}});
  EXPECT_EQ(nan.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(nan.status().field(), "parameters.ramps");
  auto above = rig.service->Start(rig.clinician, rig.session_id, "isometric_ramp_irc",
                                  {{"max_ma", rig.vs.max_tolerated_ma + 1.0}});
  EXPECT_EQ(above.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(above.status().field(), "parameters.max_ma");

  // Nothing was stored or audited for refused starts.
  auto runs = storage::SessionRepository(*rig.db).ListRuns(rig.session_id);
  ASSERT_TRUE(runs.ok());
  EXPECT_TRUE(runs->empty());
  EXPECT_TRUE(rig.AuditActions().empty());
  EXPECT_FALSE(rig.service->State().busy);
}

TEST(RunService, ASessionWithoutLimitsRunsOnlyTheToleranceTest) {
  Rig rig({.with_limits = false});
  auto refused = rig.service->Start(rig.clinician, rig.session_id, "isometric_ramp_irc", {});
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), api::ErrorCode::kFailedPrecondition);
  auto tol = rig.service->Start(rig.clinician, rig.session_id, "tolerance_test", kShortTolerance);
  ASSERT_TRUE(tol.ok()) << tol.status().ToString();
  auto view = rig.service->Wait(tol->run_id, kWait);
  ASSERT_TRUE(view.ok());
  EXPECT_EQ(view->state, RunState::kDone) << view->reason;
  ASSERT_TRUE(view->tolerance.has_value());
  // Not stopped: the ceiling, within one 5 ms sample of the 5 mA/s ramp.
  EXPECT_NEAR(view->tolerance->max_tolerated_ma, 3.0, 0.025 + 1e-9);
  EXPECT_FALSE(view->tolerance->stopped_by_clinician);
  EXPECT_EQ(view->trial_ids.size(), 1u);
}

/// The highest stimulation stored in a run's trials, mA.
double MaxStoredStim(storage::Database& db, const RunView& view) {
  double max_ma = 0.0;
  storage::TrialRepository trials(db);
  for (const std::int64_t id : view.trial_ids) {
    auto trial = trials.Get(id);
    EXPECT_TRUE(trial.ok()) << trial.status().ToString();
    if (!trial.ok() || trial->Values("stim_ma") == nullptr) continue;
    for (double u : *trial->Values("stim_ma")) max_ma = std::max(max_ma, u);
  }
  return max_ma;
}

// docs/SAFETY.md, "Tolerance test ceiling": a tolerance test on a session with a recorded max
// tolerated amplitude ramps at most to it unless a clinician gives an explicit,
// audited ceiling above it. The subject now tolerates more than the
// recorded max (it signals its own limit only at 100 mA), so only the
// ceiling ends the ramp.
TEST(RunService, ToleranceTestNeverGoesAboveTheRecordedMaxByDefault) {
  Rig rig({.subject_tolerates_ma = 100.0});
  const double max_ma = rig.vs.max_tolerated_ma;
  const protocols::ParameterValues fast = {{"settle_s", 0.2}, {"rate_ma_per_s", 5.0}};
  auto run = rig.service->Start(rig.clinician, rig.session_id, "tolerance_test", fast);
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  EXPECT_DOUBLE_EQ(run->parameters.at("ceiling_ma"), max_ma) << "the ceiling is stated";
  auto view = rig.service->Wait(run->run_id, kWait);
  ASSERT_TRUE(view.ok());
  ASSERT_EQ(view->state, RunState::kDone) << view->reason;
  const double delivered = MaxStoredStim(*rig.db, *view);
  EXPECT_LE(delivered, max_ma + 1e-9);
  EXPECT_GT(delivered, max_ma - 0.1) << "the ramp reached the recorded max";

  // start_ma at or above the ceiling, or a ceiling above the max without a
  // reason: 400 naming the field.
  auto start_above =
      rig.service->Start(rig.clinician, rig.session_id, "tolerance_test", {{"start_ma", max_ma + 5.0}});
  ASSERT_FALSE(start_above.ok());
  EXPECT_EQ(start_above.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(start_above.status().field(), "parameters.start_ma");
  auto ceiling_above = rig.service->Start(rig.clinician, rig.session_id, "tolerance_test",
                                          {{"ceiling_ma", max_ma + 4.0}});
  EXPECT_EQ(ceiling_above.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(ceiling_above.status().field(), "parameters.ceiling_ma");
  auto empty_reason = rig.service->Start(rig.clinician, rig.session_id, "tolerance_test",
                                         {{"ceiling_ma", max_ma + 4.0}}, std::string());
  EXPECT_EQ(empty_reason.status().field(), "ceiling_reason");
  auto needless_reason = rig.service->Start(rig.clinician, rig.session_id, "tolerance_test",
                                            {{"ceiling_ma", max_ma - 1.0}}, std::string("why"));
  EXPECT_EQ(needless_reason.status().field(), "ceiling_reason");
  auto other_protocol = rig.service->Start(rig.clinician, rig.session_id, "isometric_ramp_irc",
                                           {}, std::string("why"));
  EXPECT_EQ(other_protocol.status().field(), "ceiling_reason");
  auto above_hardware = rig.service->Start(rig.clinician, rig.session_id, "tolerance_test",
                                           {{"ceiling_ma", 100.5}}, std::string("why"));
  EXPECT_EQ(above_hardware.status().field(), "parameters.ceiling_ma");

  // An explicit ceiling above the max, with a reason: allowed and audited.
  protocols::ParameterValues above = fast;
  above["ceiling_ma"] = max_ma + 4.0;
  auto explicit_run = rig.service->Start(rig.clinician, rig.session_id, "tolerance_test", above,
                                         std::string("re-test after training"));
  ASSERT_TRUE(explicit_run.ok()) << explicit_run.status().ToString();
  auto explicit_view = rig.service->Wait(explicit_run->run_id, kWait);
  ASSERT_TRUE(explicit_view.ok());
  ASSERT_EQ(explicit_view->state, RunState::kDone) << explicit_view->reason;
  const double explicit_max = MaxStoredStim(*rig.db, *explicit_view);
  EXPECT_GT(explicit_max, max_ma + 3.9);
  EXPECT_LE(explicit_max, max_ma + 4.0 + 1e-9);
  storage::AuditQuery q;
  auto entries = storage::AuditLog(*rig.db).List(q);
  ASSERT_TRUE(entries.ok());
  const auto audited = std::find_if(entries->begin(), entries->end(), [](const auto& e) {
    return e.entry.action == "run.ceiling_above_max";
  });
  ASSERT_NE(audited, entries->end());
  EXPECT_EQ(audited->entry.actor, "cora");
  EXPECT_EQ(audited->entry.target, "runs/" + std::to_string(explicit_run->run_id));
  EXPECT_NE(audited->entry.request_summary.find("re-test after training"), std::string::npos);
  const std::vector<std::string> actions = rig.AuditActions();
  EXPECT_EQ(std::count(actions.begin(), actions.end(), "run.ceiling_above_max"), 1);
}

// A session without a recorded max (the first session of a new subject):
// the tolerance test finds it, up to the stated 60 mA default ceiling.
TEST(RunService, ToleranceTestWithoutARecordedMaxStatesItsDefaultCeiling) {
  Rig rig({.with_limits = false, .subject_tolerates_ma = 100.0});
  auto context = LoadSessionContext(*rig.db, rig.session_id, rig.bench->limits());
  ASSERT_TRUE(context.ok());
  EXPECT_FALSE(context->subject.max_tolerated_recorded);
  auto run = rig.service->Start(rig.clinician, rig.session_id, "tolerance_test",
                                {{"settle_s", 0.2}, {"start_ma", 55.0}, {"rate_ma_per_s", 5.0}});
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  EXPECT_DOUBLE_EQ(run->parameters.at("ceiling_ma"), 60.0);
  auto view = rig.service->Wait(run->run_id, kWait);
  ASSERT_TRUE(view.ok());
  EXPECT_EQ(view->state, RunState::kDone) << view->reason;
  const double delivered = MaxStoredStim(*rig.db, *view);
  EXPECT_LE(delivered, 60.0 + 1e-9);
  EXPECT_GT(delivered, 59.9);

  // The subject bore the whole ramp: the ceiling is not their limit, so no
  // max tolerated is recorded and the session is unchanged (docs/SAFETY.md).
  EXPECT_EQ(view->values.at("subject_signalled_limit"), 0.0);
  EXPECT_TRUE(view->result.at("max_tolerated_ma").is_null()) << view->result.dump();
  EXPECT_TRUE(view->result.at("session_revision").is_null());
  EXPECT_EQ(view->result.at("ended_at_ceiling"), true);
  const std::string message = view->result.at("message");
  EXPECT_NE(message.find("60 mA"), std::string::npos) << message;
  EXPECT_NE(message.find("re-test"), std::string::npos) << message;
  ASSERT_TRUE(view->tolerance.has_value());
  EXPECT_NE(std::find(view->tolerance->warnings.begin(), view->tolerance->warnings.end(), message),
            view->tolerance->warnings.end());
  auto session = storage::SessionRepository(*rig.db).Get(rig.session_id);
  ASSERT_TRUE(session.ok());
  EXPECT_EQ(session->current.revision, 1) << "the session was revised";
  EXPECT_FALSE(session->current.details.max_tolerated_ma.has_value());
  EXPECT_FALSE(session->current.details.threshold_ma.has_value());
}

// A new subject's first tolerance test, left running: it ends where the
// subject signals its limit, which the session then records.
TEST(RunService, ToleranceTestLeftRunningRecordsWhereTheSubjectSignalledTheLimit) {
  Rig rig({.with_limits = false});
  const double limit = rig.vs.max_tolerated_ma;
  ASSERT_LT(limit, 58.0);
  auto run =
      rig.service->Start(rig.clinician, rig.session_id, "tolerance_test",
                         {{"settle_s", 0.2}, {"start_ma", limit - 2.0}, {"rate_ma_per_s", 5.0}});
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  auto view = rig.service->Wait(run->run_id, kWait);
  ASSERT_TRUE(view.ok());
  ASSERT_EQ(view->state, RunState::kDone) << view->reason;
  EXPECT_EQ(view->values.at("subject_signalled_limit"), 1.0);
  EXPECT_EQ(view->result.at("subject_signalled_limit"), true);
  const double recorded = view->result.at("max_tolerated_ma").get<double>();
  EXPECT_GE(recorded, limit);
  EXPECT_LT(recorded, limit + 0.25);
  EXPECT_LT(MaxStoredStim(*rig.db, *view), limit + 0.25);
  EXPECT_FALSE(view->result.contains("ended_at_ceiling"));
  auto session = storage::SessionRepository(*rig.db).Get(rig.session_id);
  ASSERT_TRUE(session.ok());
  EXPECT_EQ(session->current.revision, 2);
  ASSERT_TRUE(session->current.details.max_tolerated_ma.has_value());
  EXPECT_DOUBLE_EQ(*session->current.details.max_tolerated_ma, recorded);
}

// Restart (docs/SAFETY.md, "Shutdown and restart") in process: a new RunService on the same
// database (a restart) closes the runs left open and latches a stored e-stop again.
TEST(RunService, RecoveryClosesRunsLeftOpenAndLatchesAStoredEStopAgain) {
  Rig rig;
  storage::SessionRepository sessions(*rig.db);
  auto queued = sessions.CreateRun(rig.session_id, {"tolerance_test", "1", "{}"});
  auto running = sessions.CreateRun(rig.session_id, {"isometric_ramp_irc", "1", "{}"});
  auto done = sessions.CreateRun(rig.session_id, {"isometric_ramp_irc", "1", "{}"});
  ASSERT_TRUE(queued.ok() && running.ok() && done.ok());
  ASSERT_TRUE(sessions.RecordRunState(running->id, RunState::kRunning).ok());
  ASSERT_TRUE(sessions.RecordRunState(done->id, RunState::kRunning).ok());
  ASSERT_TRUE(sessions.RecordRunState(done->id, RunState::kDone).ok());
  // The previous process's e-stop, as it stored it.
  ASSERT_TRUE(rig.service->EStop(rig.analyst, "http").ok());
  storage::EStopLatchRepository latch(*rig.db);
  auto stored = latch.Current();
  ASSERT_TRUE(stored.ok());
  ASSERT_TRUE(stored->has_value()) << "the e-stop is stored as it latches";
  EXPECT_EQ((*stored)->source, "http (ana)");

  // Restart: a new service (a fresh SafeBench, not latched) on the same
  // database, and a simulated bench that starts unlatched as a new process's does.
  rig.service.reset();
  rig.bench->ClearHardwareEStop();
  rig.service = std::make_unique<RunService>(*rig.db, *rig.bench, rig.hub, rig.config);
  EXPECT_FALSE(rig.service->State().estopped);
  auto recovery = rig.service->RecoverAfterRestart();
  ASSERT_TRUE(recovery.ok()) << recovery.status().ToString();
  EXPECT_EQ(recovery->failed_run_ids, (std::vector<std::int64_t>{queued->id, running->id}));
  ASSERT_TRUE(recovery->estop_source.has_value());
  EXPECT_EQ(*recovery->estop_source, "http (ana)");
  for (const std::int64_t id : recovery->failed_run_ids) {
    auto run = sessions.GetRun(id);
    ASSERT_TRUE(run.ok());
    EXPECT_EQ(run->state, RunState::kFailed);
    EXPECT_EQ(run->message, "server stopped during the run");
    auto view = rig.service->Get(id);
    ASSERT_TRUE(view.ok());
    EXPECT_EQ(view->reason, "server stopped during the run");
  }
  EXPECT_EQ(sessions.GetRun(done->id)->state, RunState::kDone);
  EXPECT_TRUE(rig.service->State().estopped);
  EXPECT_EQ(rig.service->State().estop_source, "http (ana)");
  auto refused =
      rig.service->Start(rig.clinician, rig.session_id, "tolerance_test", kShortTolerance);
  EXPECT_EQ(refused.status().code(), api::ErrorCode::kConflict);
  std::vector<std::string> actions = rig.AuditActions();
  EXPECT_EQ(std::count(actions.begin(), actions.end(), "run.recovered"), 2);
  EXPECT_EQ(std::count(actions.begin(), actions.end(), "bench.estop_restored"), 1);

  // Only a person clears it; then the stored latch is clear too.
  EXPECT_EQ(rig.service->ClearEStop(rig.analyst).code(), api::ErrorCode::kPermissionDenied);
  EXPECT_TRUE(latch.Current()->has_value());
  ASSERT_TRUE(rig.service->ClearEStop(rig.clinician).ok());
  EXPECT_FALSE(latch.Current()->has_value());
  actions = rig.AuditActions();
  EXPECT_EQ(std::count(actions.begin(), actions.end(), "bench.clear_estop"), 1);

  // Another restart: nothing left to close, nothing latched.
  rig.service.reset();
  rig.service = std::make_unique<RunService>(*rig.db, *rig.bench, rig.hub, rig.config);
  auto again = rig.service->RecoverAfterRestart();
  ASSERT_TRUE(again.ok());
  EXPECT_TRUE(again->failed_run_ids.empty());
  EXPECT_FALSE(again->estop_source.has_value());
  EXPECT_FALSE(rig.service->State().estopped);
}

TEST(RunService, LoadSessionContextTakesLimitsAnthropometricsAndTheLatestSet) {
  Rig rig;
  auto c = LoadSessionContext(*rig.db, rig.session_id, rig.bench->limits());
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_TRUE(c->has_stimulation_limits);
  EXPECT_DOUBLE_EQ(c->subject.threshold_ma, rig.vs.threshold_ma);
  EXPECT_DOUBLE_EQ(c->subject.max_tolerated_ma, rig.vs.max_tolerated_ma);
  EXPECT_DOUBLE_EQ(c->subject.min_angle_deg, 10.0);
  EXPECT_DOUBLE_EQ(c->subject.max_angle_deg, 110.0);
  ASSERT_TRUE(c->subject.body_mass_kg.has_value());
  EXPECT_DOUBLE_EQ(*c->subject.body_mass_kg, rig.vs.anthropometrics.body_mass_kg);
  ASSERT_TRUE(c->subject.leg_length_m.has_value());
  EXPECT_NEAR(*c->subject.leg_length_m, rig.vs.anthropometrics.shank_length_m, 1e-12);
  EXPECT_FALSE(c->subject.inertia_kgm2.has_value());
  EXPECT_FALSE(c->subject.parameter_set.has_value());
  EXPECT_FALSE(c->parameter_set_id.has_value());
  EXPECT_EQ(LoadSessionContext(*rig.db, 4242, rig.bench->limits()).status().code(),
            api::ErrorCode::kNotFound);

  // The subject's recorded range of motion narrows the bench's (the safety
  // layer enforces what the context says); a wider one leaves the bench's.
  storage::SubjectRepository subjects(*rig.db);
  storage::SubjectDetails d = subjects.Get(rig.subject_id)->current.details;
  d.rom_min_deg = 20.0;
  d.rom_max_deg = 90.0;
  ASSERT_TRUE(subjects.Correct(rig.subject_id, d, "stiff knee").ok());
  auto narrowed = LoadSessionContext(*rig.db, rig.session_id, rig.bench->limits());
  ASSERT_TRUE(narrowed.ok());
  EXPECT_DOUBLE_EQ(narrowed->subject.min_angle_deg, 20.0);
  EXPECT_DOUBLE_EQ(narrowed->subject.max_angle_deg, 90.0);
  d.rom_min_deg = -10.0;
  d.rom_max_deg = 140.0;
  ASSERT_TRUE(subjects.Correct(rig.subject_id, d, "measured again").ok());
  auto wider = LoadSessionContext(*rig.db, rig.session_id, rig.bench->limits());
  ASSERT_TRUE(wider.ok());
  EXPECT_DOUBLE_EQ(wider->subject.min_angle_deg, 10.0);
  EXPECT_DOUBLE_EQ(wider->subject.max_angle_deg, 110.0);

  // A passive-only set can never be approved, so it holds nothing back; a
  // candidate that could be approved does (docs/SAFETY.md).
  storage::ParameterSetRepository sets(*rig.db);
  model::ParameterSet passive_only = model::ExampleParameterSet();
  passive_only.provenance.irc_method = "none";
  passive_only.provenance.active_method = "none";
  ASSERT_TRUE(sets.Insert({rig.subject_id, rig.leg_id, passive_only, std::nullopt, std::nullopt})
                  .ok());
  auto with_passive = LoadSessionContext(*rig.db, rig.session_id, rig.bench->limits());
  ASSERT_TRUE(with_passive.ok());
  EXPECT_FALSE(with_passive->subject.sets_await_approval);
  ASSERT_TRUE(sets.Insert({rig.subject_id, rig.leg_id, model::ExampleParameterSet(), std::nullopt,
                           std::nullopt})
                  .ok());
  auto with_candidate = LoadSessionContext(*rig.db, rig.session_id, rig.bench->limits());
  ASSERT_TRUE(with_candidate.ok());
  EXPECT_TRUE(with_candidate->subject.sets_await_approval);
}

}  // namespace
}  // namespace fesbench::server::services
