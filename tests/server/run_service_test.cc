// RunService on the simulated bench with a temporary database: runs for
// stored sessions end in stored states, trials, parameter sets and audit
// rows; one run at a time; e-stop latches until cleared; heartbeat
// watchdog; cancel; shutdown; live samples to subscribers in order, and a
// subscriber that never reads does not hold the run up; unknown ids and bad
// input are refused with the right codes.
#include "server/services/run_service.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <map>
#include <set>
#include <thread>

#include "server/bench/virtual_subject.h"
#include "server/protocols/plan.h"
#include "server/protocols/rapid_identification.h"
#include "server/services/bench_service.h"
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

// --- a run from start to stored end ---------------------------------------------

TEST(RunService, IsometricRampRunStoresStatesTrialsAndAudit) {
  Rig rig;
  const protocols::Plan plan = rig.PlanFor("isometric_ramp_irc", {});
  SubscribeOptions all;
  all.capacity = 100000;
  auto sub = rig.hub.Subscribe(all);
  ASSERT_NE(sub->Next(0ms), nullptr);  // the idle state

  auto started = rig.service->Start(rig.clinician, rig.session_id, "isometric_ramp_irc", {});
  ASSERT_TRUE(started.ok()) << started.status().ToString();
  const std::int64_t run_id = started->run_id;
  EXPECT_GT(run_id, 0);
  EXPECT_EQ(started->session_id, rig.session_id);
  EXPECT_EQ(started->protocol, "isometric_ramp_irc");
  EXPECT_EQ(started->owner, "cora");
  EXPECT_EQ(started->owner_user_id, rig.clinician.user_id);
  EXPECT_NEAR(started->progress.bench_total_s, plan.duration_s(), 1e-9);
  EXPECT_EQ(started->parameters, plan.parameters);

  const Stream stream = Read(*sub);
  auto view = rig.service->Wait(run_id, kWait);
  ASSERT_TRUE(view.ok());
  EXPECT_EQ(view->state, RunState::kDone) << view->reason;
  EXPECT_TRUE(view->reason.empty());
  EXPECT_TRUE(view->live);
  EXPECT_DOUBLE_EQ(view->progress.fraction, 1.0);
  ASSERT_TRUE(view->started_at.has_value());
  ASSERT_TRUE(view->finished_at.has_value());
  EXPECT_LE(view->created_at, *view->started_at);
  EXPECT_LE(*view->started_at, *view->finished_at);
  EXPECT_FALSE(view->parameter_set_id.has_value());

  // The stored run: queued → running → completed.
  auto run = storage::SessionRepository(*rig.db).GetRun(run_id);
  ASSERT_TRUE(run.ok());
  EXPECT_EQ(run->state, storage::RunState::kDone);
  EXPECT_EQ(run->protocol_name, "isometric_ramp_irc");
  EXPECT_EQ(run->protocol_version, std::to_string(plan.protocol_version));
  EXPECT_EQ(nlohmann::json::parse(run->parameters_json).at("ramps"), plan.parameters.at("ramps"));
  EXPECT_EQ(run->started_at, view->started_at);
  EXPECT_EQ(run->finished_at, view->finished_at);
  ASSERT_TRUE(run->bench_s.has_value());
  EXPECT_NEAR(*run->bench_s, plan.duration_s(), 1e-9);  // done: it ran the whole plan
  EXPECT_NEAR(run->bench_planned_s.value_or(0.0), plan.duration_s(), 1e-9);

  // Every planned trial, stored with all channels, as many samples as streamed.
  ASSERT_EQ(view->trial_ids.size(), plan.trials.size());
  storage::TrialRepository trials(*rig.db);
  std::size_t stored_samples = 0;
  for (std::size_t k = 0; k < view->trial_ids.size(); ++k) {
    auto trial = trials.Get(view->trial_ids[k]);
    ASSERT_TRUE(trial.ok()) << trial.status().ToString();
    EXPECT_EQ(trial->name, plan.trials[k].name);
    EXPECT_DOUBLE_EQ(trial->sample_rate_hz, 200.0);
    for (const char* channel :
         {"t_s", "stim_ma", "stim_delivered_ma", "angle_deg", "torque_nm", "accel_m_s2"}) {
      ASSERT_NE(trial->Values(channel), nullptr) << channel;
      EXPECT_EQ(trial->Values(channel)->size(), trial->num_samples()) << channel;
    }
    // The delivered pulses went through storage with the trial.
    ASSERT_TRUE(trial->pulses.has_value());
    EXPECT_EQ(trial->pulses->pulse_rate_hz, 33.0);
    EXPECT_GT(trial->num_samples(), 200u);
    EXPECT_EQ(stream.samples_per_trial.at(static_cast<int>(k)), trial->num_samples());
    stored_samples += trial->num_samples();
    auto owner = trials.Owner(view->trial_ids[k]);
    ASSERT_TRUE(owner.ok());
    EXPECT_EQ(owner->run_id, run_id);
    EXPECT_EQ(owner->session_id, rig.session_id);
  }

  // The stream: every sample in order, then the end.
  EXPECT_TRUE(stream.ended);
  EXPECT_TRUE(stream.in_order);
  EXPECT_EQ(stream.dropped, 0u);
  EXPECT_EQ(stream.samples, stored_samples);
  EXPECT_EQ(stream.items.back()->kind, HubItem::Kind::kEnd);
  EXPECT_EQ(stream.items.back()->state, RunState::kDone);
  // Progress: 0–1, non-decreasing, ending at 1; ETA at time scale 0 is the
  // measured wall rate times what is left, so never negative.
  double last_fraction = 0.0;
  int progress_items = 0;
  for (const HubItemPtr& item : stream.items) {
    if (item->kind != HubItem::Kind::kProgress) continue;
    ++progress_items;
    EXPECT_GE(item->progress.fraction, last_fraction);
    EXPECT_LE(item->progress.fraction, 1.0);
    EXPECT_GE(item->progress.eta_s, 0.0);
    last_fraction = item->progress.fraction;
  }
  EXPECT_GT(progress_items, 10);
  EXPECT_DOUBLE_EQ(last_fraction, 1.0);

  // Audit: start, running, one row per trial, finish — by the clinician.
  std::vector<std::string> expected = {"run.start", "run.state"};
  for (std::size_t k = 0; k < plan.trials.size(); ++k) expected.push_back("trial.record");
  expected.push_back("run.finish");
  EXPECT_EQ(rig.AuditActions(), expected);
  auto audit = storage::AuditLog(*rig.db).List({});
  ASSERT_TRUE(audit.ok());
  for (const auto& e : *audit) {
    EXPECT_EQ(e.entry.user_id, rig.clinician.user_id);
    EXPECT_EQ(e.entry.actor, "cora");
  }
  EXPECT_TRUE(rig.logs.empty());

  // A fresh service reads the same run back from storage.
  RunService fresh(*rig.db, *rig.bench, rig.hub, rig.config);
  auto stored = fresh.Get(run_id);
  ASSERT_TRUE(stored.ok());
  EXPECT_FALSE(stored->live);
  EXPECT_EQ(stored->state, RunState::kDone);
  EXPECT_EQ(stored->trial_ids, view->trial_ids);
  EXPECT_EQ(stored->parameters, view->parameters);
  EXPECT_EQ(stored->finished_at, view->finished_at);
  const nlohmann::json j = api::RunViewToJson(*view);
  EXPECT_EQ(j.at("state"), "done");
  EXPECT_EQ(j.at("trial_ids").size(), plan.trials.size());
}

TEST(RunService, RapidProtocolStoresAParameterSetWhoseProvenanceTrialsExist) {
  Rig rig;
  const protocols::Plan plan = rig.PlanFor("rapid_parameterisation", {});
  const auto* identification =
      dynamic_cast<const protocols::RapidIdentification*>(plan.analysis.get());
  ASSERT_NE(identification, nullptr);
  const protocols::RapidSettings& rapid = identification->settings();
  auto started = rig.service->Start(rig.clinician, rig.session_id, "rapid_parameterisation", {});
  ASSERT_TRUE(started.ok()) << started.status().ToString();
  auto view = rig.service->Wait(started->run_id, kWait);
  ASSERT_TRUE(view.ok());
  ASSERT_EQ(view->state, RunState::kDone) << view->reason;
  ASSERT_EQ(view->trial_ids.size(), plan.trials.size());
  ASSERT_TRUE(view->parameter_set_id.has_value());

  storage::ParameterSetRepository sets(*rig.db);
  auto set = sets.Get(*view->parameter_set_id);
  ASSERT_TRUE(set.ok()) << set.status().ToString();
  EXPECT_EQ(set->summary.subject_id, rig.subject_id);
  EXPECT_EQ(set->summary.leg_id, rig.leg_id);
  EXPECT_EQ(set->summary.version, 1);
  // Every trial the set was fitted to: ramp, the holds before the releases,
  // the free swings, random binary.
  std::vector<std::int64_t> used = {
      view->trial_ids[static_cast<std::size_t>(rapid.ramp_trial)],
      view->trial_ids[static_cast<std::size_t>(rapid.active_trial)]};
  for (int k : rapid.swing_trials) used.push_back(view->trial_ids[static_cast<std::size_t>(k)]);
  for (const auto& [hold, swing] : rapid.release_trials)
    used.push_back(view->trial_ids[static_cast<std::size_t>(hold)]);
  std::sort(used.begin(), used.end());
  EXPECT_EQ(set->trial_ids, used);
  EXPECT_EQ(set->params.provenance.trial_ids, used);
  EXPECT_EQ(set->params.provenance.active_trial_id,
            view->trial_ids[static_cast<std::size_t>(rapid.active_trial)]);
  storage::TrialRepository trials(*rig.db);
  for (std::int64_t id : set->trial_ids) {
    auto owner = trials.Owner(id);
    ASSERT_TRUE(owner.ok()) << id;
    EXPECT_EQ(owner->run_id, started->run_id);
  }
  // J measured by the releases, starting from Eq. 4.13 on the stored
  // anthropometrics (no prior set): near the leg's, not Eq. 4.13's.
  EXPECT_EQ(set->params.provenance.inertia_method, "releases");
  EXPECT_NEAR(set->params.passive.inertia_kgm2, rig.vs.truth.passive.inertia_kgm2,
              0.1 * rig.vs.truth.passive.inertia_kgm2);
  auto latest = sets.Latest(rig.subject_id, rig.leg_id);
  ASSERT_TRUE(latest.ok());
  EXPECT_EQ(latest->summary.id, *view->parameter_set_id);

  const std::vector<std::string> actions = rig.AuditActions();
  ASSERT_FALSE(actions.empty());
  EXPECT_EQ(actions.back(), "run.finish");
  auto audit = storage::AuditLog(*rig.db).List({});
  ASSERT_TRUE(audit.ok());
  EXPECT_NE(audit->front().entry.request_summary.find("parameter set " +
                                                      std::to_string(*view->parameter_set_id)),
            std::string::npos);

  // Read back from storage by a fresh service: the set is found again.
  RunService fresh(*rig.db, *rig.bench, rig.hub, rig.config);
  auto stored = fresh.Get(started->run_id);
  ASSERT_TRUE(stored.ok());
  EXPECT_EQ(stored->parameter_set_id, view->parameter_set_id);

  // A second rapid run supersedes the first set and now takes the prior
  // set's inertia (the model gate and the fit see the leg's latest set).
  auto again = rig.service->Start(rig.clinician, rig.session_id, "rapid_parameterisation", {});
  ASSERT_TRUE(again.ok()) << again.status().ToString();
  auto second = rig.service->Wait(again->run_id, kWait);
  ASSERT_TRUE(second.ok());
  ASSERT_EQ(second->state, RunState::kDone) << second->reason;
  ASSERT_TRUE(second->parameter_set_id.has_value());
  auto set2 = sets.Get(*second->parameter_set_id);
  ASSERT_TRUE(set2.ok());
  EXPECT_EQ(set2->summary.version, 2);
  EXPECT_EQ(set2->summary.supersedes_id, view->parameter_set_id);

  // Each run's set is approved by its run (docs/SAFETY.md): the leg's
  // approved set is the second. A newer set nobody approved (an import, a
  // re-identification) changes nothing, and tracking may not name it.
  auto approval = sets.LegApproval(rig.leg_id);
  ASSERT_TRUE(approval.ok() && approval->has_value());
  EXPECT_EQ((*approval)->parameter_set_id, *second->parameter_set_id);
  EXPECT_EQ((*approval)->run_id, again->run_id);
  EXPECT_EQ((*approval)->approved_by, rig.clinician.user_name);
  storage::NewParameterSet candidate{rig.subject_id, rig.leg_id, set2->params, std::nullopt,
                                     std::nullopt};
  auto unapproved = sets.Insert(candidate);
  ASSERT_TRUE(unapproved.ok()) << unapproved.status().ToString();
  auto context = LoadSessionContext(*rig.db, rig.session_id, rig.bench->limits());
  ASSERT_TRUE(context.ok());
  EXPECT_EQ(context->parameter_set_id, second->parameter_set_id);
  EXPECT_EQ(context->subject.parameter_set_id, second->parameter_set_id);
  EXPECT_FALSE(context->subject.sets_await_approval);
  auto tracking = rig.service->Start(rig.clinician, rig.session_id, "tracking",
                                     {{"parameter_set_id", static_cast<double>(unapproved->id)}});
  ASSERT_FALSE(tracking.ok());
  EXPECT_EQ(tracking.status().code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_NE(tracking.status().message().find("never approved"), std::string::npos)
      << tracking.status().ToString();
}

// --- one run at a time, cancel, e-stop, watchdog, shutdown ----------------------------

TEST(RunService, SecondStartConflictsAndCancelAbortsTheRun) {
  Rig rig({.time_scale = 1.0});
  auto first = rig.service->Start(rig.clinician, rig.session_id, "isometric_ramp_irc", {});
  ASSERT_TRUE(first.ok()) << first.status().ToString();
  auto second = rig.service->Start(rig.admin, rig.session_id, "isometric_step_irc", {});
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.status().code(), api::ErrorCode::kConflict);
  EXPECT_NE(second.status().message().find("cora"), std::string::npos);

  const BenchState state = rig.service->State();
  EXPECT_TRUE(state.busy);
  EXPECT_EQ(state.owner, "cora");
  EXPECT_EQ(state.run_id, first->run_id);
  EXPECT_EQ(state.mode, "locked");

  EXPECT_EQ(rig.service->Cancel(rig.analyst, first->run_id).code(),
            api::ErrorCode::kPermissionDenied);
  ASSERT_TRUE(rig.service->Cancel(rig.clinician, first->run_id).ok());
  auto view = rig.service->Wait(first->run_id, kWait);
  ASSERT_TRUE(view.ok());
  EXPECT_EQ(view->state, RunState::kAborted);
  EXPECT_EQ(view->reason, "cancelled by cora");
  EXPECT_LT(view->progress.fraction, 0.5);
  auto run = storage::SessionRepository(*rig.db).GetRun(first->run_id);
  ASSERT_TRUE(run.ok());
  EXPECT_EQ(run->state, storage::RunState::kAborted);
  EXPECT_EQ(run->message, "cancelled by cora");
  // The bench time stored is the time it ran, not the plan's; the stored
  // view (what a restarted server answers) shows both.
  const protocols::Plan plan = rig.PlanFor("isometric_ramp_irc", {});
  ASSERT_TRUE(run->bench_s.has_value());
  EXPECT_DOUBLE_EQ(*run->bench_s, view->progress.bench_total_s);
  EXPECT_LT(*run->bench_s, 0.5 * plan.duration_s());
  EXPECT_DOUBLE_EQ(run->bench_planned_s.value_or(0.0), plan.duration_s());
  const api::RunView stored = storage::RunViewOf(*run);
  EXPECT_DOUBLE_EQ(stored.progress.bench_total_s, *run->bench_s);
  EXPECT_DOUBLE_EQ(stored.progress.bench_elapsed_s, *run->bench_s);
  EXPECT_DOUBLE_EQ(stored.progress.bench_planned_s, plan.duration_s());
  EXPECT_DOUBLE_EQ(rig.bench->ReadSensors().stim_ma, 0.0);
  EXPECT_FALSE(rig.service->State().busy);

  // Cancelling it again: it exists but is over.
  EXPECT_EQ(rig.service->Cancel(rig.clinician, first->run_id).code(), api::ErrorCode::kConflict);
  const std::vector<std::string> actions = rig.AuditActions();
  EXPECT_NE(std::find(actions.begin(), actions.end(), "run.cancel"), actions.end());
}

TEST(RunService, EStopAbortsLatchesAndClearsByClinicianOnly) {
  Rig rig({.time_scale = 1.0});
  auto run = rig.service->Start(rig.clinician, rig.session_id, "isometric_ramp_irc", {});
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  WaitRunning(*rig.service, run->run_id);
  // Any role may stop the bench.
  ASSERT_TRUE(rig.service->EStop(rig.analyst, "http").ok());
  auto view = rig.service->Wait(run->run_id, kWait);
  ASSERT_TRUE(view.ok());
  EXPECT_EQ(view->state, RunState::kAborted);
  EXPECT_EQ(view->reason, "e-stop");
  EXPECT_TRUE(
      std::any_of(view->safety_events.begin(), view->safety_events.end(),
                  [](const SafetyEvent& e) { return e.kind == SafetyEvent::Kind::kEStop; }));
  EXPECT_DOUBLE_EQ(rig.bench->ReadSensors().stim_ma, 0.0);
  auto stored = storage::SessionRepository(*rig.db).GetRun(run->run_id);
  ASSERT_TRUE(stored.ok());
  EXPECT_EQ(stored->state, storage::RunState::kAborted);
  EXPECT_EQ(stored->message, "e-stop");

  BenchState state = rig.service->State();
  EXPECT_TRUE(state.estopped);
  EXPECT_EQ(state.estop_source, "http (ana)");
  auto refused =
      rig.service->Start(rig.clinician, rig.session_id, "tolerance_test", kShortTolerance);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), api::ErrorCode::kConflict);

  EXPECT_EQ(rig.service->ClearEStop(rig.analyst).code(), api::ErrorCode::kPermissionDenied);
  EXPECT_TRUE(rig.service->State().estopped);
  ASSERT_TRUE(rig.service->ClearEStop(rig.clinician).ok());
  state = rig.service->State();
  EXPECT_FALSE(state.estopped);
  EXPECT_TRUE(state.estop_source.empty());

  auto next = rig.service->Start(rig.clinician, rig.session_id, "tolerance_test", kShortTolerance);
  ASSERT_TRUE(next.ok()) << next.status().ToString();
  auto done = rig.service->Wait(next->run_id, kWait);
  ASSERT_TRUE(done.ok());
  EXPECT_EQ(done->state, RunState::kDone) << done->reason;
  ASSERT_TRUE(done->tolerance.has_value());

  const std::vector<std::string> actions = rig.AuditActions();
  EXPECT_EQ(std::count(actions.begin(), actions.end(), "bench.estop"), 1);
  EXPECT_EQ(std::count(actions.begin(), actions.end(), "bench.clear_estop"), 1);
}

// docs/SAFETY.md, "One server per bench": a server that lost its bench lock
// stops the run as an e-stop does, latches, and refuses runs and the clearing
// of the e-stop (503 naming the lock) until it holds the bench again.
TEST(RunService, ALostBenchStopsTheRunLatchesAndRefusesUntilItIsRegained) {
  Rig rig({.time_scale = 1.0});
  auto run = rig.service->Start(rig.clinician, rig.session_id, "isometric_ramp_irc", {});
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  WaitRunning(*rig.service, run->run_id);
  const std::string reason = "this server lost its lock on bench 'knee-a' (killed)";
  rig.service->LoseBench(reason);
  auto view = rig.service->Wait(run->run_id, kWait);
  ASSERT_TRUE(view.ok());
  EXPECT_EQ(view->state, RunState::kAborted);
  EXPECT_DOUBLE_EQ(rig.bench->ReadSensors().stim_ma, 0.0);
  EXPECT_TRUE(rig.service->State().estopped);
  EXPECT_EQ(rig.service->State().estop_source, "bench lock lost (system)");
  auto latched = storage::EStopLatchRepository(*rig.db).Current();
  ASSERT_TRUE(latched.ok() && latched->has_value());

  auto refused =
      rig.service->Start(rig.clinician, rig.session_id, "tolerance_test", kShortTolerance);
  EXPECT_EQ(refused.status().code(), api::ErrorCode::kUnavailable);
  EXPECT_EQ(refused.status().message(), reason);
  EXPECT_EQ(rig.service->ClearEStop(rig.clinician).code(), api::ErrorCode::kUnavailable);
  rig.service->LoseBench(reason + " again");  // no second latch while lost
  std::vector<std::string> actions = rig.AuditActions();
  EXPECT_EQ(std::count(actions.begin(), actions.end(), "bench.estop"), 1);

  rig.service->RegainBench();
  auto latched_still =
      rig.service->Start(rig.clinician, rig.session_id, "tolerance_test", kShortTolerance);
  EXPECT_EQ(latched_still.status().code(), api::ErrorCode::kConflict);  // a person clears it
  ASSERT_TRUE(rig.service->ClearEStop(rig.clinician).ok());
  auto next = rig.service->Start(rig.clinician, rig.session_id, "tolerance_test", kShortTolerance);
  ASSERT_TRUE(next.ok()) << next.status().ToString();
  EXPECT_TRUE(rig.service->Wait(next->run_id, kWait).ok());
}

TEST(RunService, WatchdogStopsARunWithoutHeartbeatsAndHeartbeatsKeepItGoing) {
  // Wall clock = bench time, so the 1 s watchdog is exact at time scale 0.
  Rig rig({.arm_watchdog = true, .wall_clock_is_bench_time = true});
  auto silent = rig.service->Start(rig.clinician, rig.session_id, "isometric_ramp_irc", {});
  ASSERT_TRUE(silent.ok()) << silent.status().ToString();
  auto aborted = rig.service->Wait(silent->run_id, kWait);
  ASSERT_TRUE(aborted.ok());
  EXPECT_EQ(aborted->state, RunState::kAborted);
  EXPECT_NE(aborted->reason.find("watchdog"), std::string::npos) << aborted->reason;

  // The owner heartbeats every 0.5 s of the run; another user may not.
  std::atomic<int> beats{0};
  std::atomic<int> refused{0};
  double next_beat_s = 0.0;
  rig.hook = [&](double t_s) {
    if (t_s < next_beat_s) return;
    const std::optional<std::int64_t> run_id = rig.service->State().run_id;
    if (!run_id) return;
    next_beat_s = t_s + 0.5;
    if (rig.service->Heartbeat(rig.clinician, *run_id).ok()) ++beats;
    if (rig.service->Heartbeat(rig.admin, *run_id).code() == api::ErrorCode::kPermissionDenied) {
      ++refused;
    }
  };
  auto kept = rig.service->Start(rig.clinician, rig.session_id, "isometric_ramp_irc", {});
  ASSERT_TRUE(kept.ok()) << kept.status().ToString();
  auto done = rig.service->Wait(kept->run_id, kWait);
  ASSERT_TRUE(done.ok());
  EXPECT_GT(beats.load(), 10);
  EXPECT_EQ(refused.load(), beats.load());
  EXPECT_EQ(done->state, RunState::kDone) << done->reason;
}

TEST(RunService, ShutdownCancelsTheRunSafelyAndRefusesNewOnes) {
  Rig rig({.time_scale = 1.0});
  auto run = rig.service->Start(rig.clinician, rig.session_id, "isometric_ramp_irc", {});
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  rig.service->Shutdown();
  auto view = rig.service->Get(run->run_id);
  ASSERT_TRUE(view.ok());
  EXPECT_EQ(view->state, RunState::kAborted);
  EXPECT_EQ(view->reason, "server shutting down");
  EXPECT_DOUBLE_EQ(rig.bench->ReadSensors().stim_ma, 0.0);
  auto stored = storage::SessionRepository(*rig.db).GetRun(run->run_id);
  ASSERT_TRUE(stored.ok());
  EXPECT_EQ(stored->state, storage::RunState::kAborted);
  auto refused =
      rig.service->Start(rig.clinician, rig.session_id, "tolerance_test", kShortTolerance);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), api::ErrorCode::kUnavailable);
  rig.service->Shutdown();  // idempotent
}

// --- live samples ------------------------------------------------------------------------

void ExpectEverySampleInOrder(Rig& rig, const std::string& protocol,
                              const protocols::ParameterValues& values) {
  SubscribeOptions big;
  big.capacity = 100000;
  SubscribeOptions tiny;
  tiny.capacity = 2;
  auto stuck = rig.hub.Subscribe(tiny);  // never read during the run
  auto reader = rig.hub.Subscribe(big);
  Stream stream;
  std::thread t([&] { stream = Read(*reader); });
  auto started = rig.service->Start(rig.clinician, rig.session_id, protocol, values);
  ASSERT_TRUE(started.ok()) << started.status().ToString();
  t.join();
  auto view = rig.service->Wait(started->run_id, kWait);
  ASSERT_TRUE(view.ok());
  ASSERT_EQ(view->state, RunState::kDone) << view->reason;

  EXPECT_TRUE(stream.ended);
  EXPECT_TRUE(stream.in_order);
  EXPECT_EQ(stream.dropped, 0u);
  std::size_t stored = 0;
  for (std::int64_t id : view->trial_ids) {
    auto trial = storage::TrialRepository(*rig.db).Get(id);
    ASSERT_TRUE(trial.ok());
    stored += trial->num_samples();
  }
  EXPECT_GT(stored, 0u);
  EXPECT_EQ(stream.samples, stored);
  // The stuck subscriber lost all but its last two items, the last being the end.
  EXPECT_GT(stuck->dropped(), 0u);
  HubItemPtr a = stuck->Next(0ms);
  HubItemPtr b = stuck->Next(0ms);
  ASSERT_NE(b, nullptr);
  EXPECT_EQ(b->kind, HubItem::Kind::kEnd);
  EXPECT_EQ(stuck->Next(0ms), nullptr);
}

TEST(RunService, SubscribersGetEverySampleInOrderAtTimeScaleZeroWhileAStuckOneDropsOnly) {
  Rig rig;
  ExpectEverySampleInOrder(rig, "isometric_ramp_irc", {});
}

TEST(RunService, SubscribersGetEverySampleInOrderInRealTimeWithTheEta) {
  Rig rig({.time_scale = 1.0});
  SubscribeOptions big;
  big.capacity = 100000;
  auto progress_reader = rig.hub.Subscribe(big);
  ExpectEverySampleInOrder(rig, "tolerance_test", kShortTolerance);
  // At time scale 1 the ETA is the bench time left.
  int n = 0;
  while (HubItemPtr item = progress_reader->Next(0ms)) {
    if (item->kind != HubItem::Kind::kProgress) continue;
    ++n;
    EXPECT_NEAR(item->progress.eta_s, item->progress.bench_total_s - item->progress.bench_elapsed_s,
                1e-9);
  }
  EXPECT_GT(n, 3);
}

}  // namespace
}  // namespace fesbench::server::services
