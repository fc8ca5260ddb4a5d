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
#include "server/services/bench_service.h"
#include "storage/audit_log.h"
#include "storage/estop_latch.h"
#include "storage/parameter_sets.h"
#include "storage/subjects.h"
#include "storage/trials.h"
#include "storage/users.h"

namespace fesbench::server::services {
namespace {

using namespace std::chrono_literals;
using protocols::RunState;

constexpr auto kWait = 120s;  // only reached if something hangs

std::filesystem::path TempDir() {
  static std::atomic<int> counter{0};
  const auto dir =
      std::filesystem::temp_directory_path() /
      ("fesbench_runsvc_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

struct RigOptions {
  double time_scale = 0.0;
  bool arm_watchdog = false;
  bool wall_clock_is_bench_time = false;
  bool with_limits = true;  // the session records threshold and max tolerated
};

/// A database with users, a subject, a leg and a session, a simulated bench
/// with a seeded virtual subject, a hub and the service.
struct Rig {
  explicit Rig(RigOptions o = {}) : options(o), dir(TempDir()) {
    storage::DatabaseOptions dbo;
    dbo.path = (dir / "fesbench.db").string();
    dbo.synchronous = storage::Synchronous::kNormal;
    auto opened = storage::Database::Open(dbo);
    EXPECT_TRUE(opened.ok()) << opened.status().ToString();
    db = std::move(opened).value();

    storage::UserRepository users(*db);
    clinician = Make(users, "cora", storage::Role::kClinician, Role::kClinician);
    analyst = Make(users, "ana", storage::Role::kAnalyst, Role::kAnalyst);
    admin = Make(users, "adam", storage::Role::kAdmin, Role::kAdmin);

    vs = DrawVirtualSubject(11);
    storage::SubjectDetails details;
    details.weight_kg = vs.anthropometrics.body_mass_kg;
    details.height_cm = vs.anthropometrics.height_m * 100.0;
    details.shank_length_cm = vs.anthropometrics.shank_length_m * 100.0;
    storage::SubjectRepository subjects(*db);
    auto subject = subjects.Create("S011", details);
    EXPECT_TRUE(subject.ok()) << subject.status().ToString();
    subject_id = subject->id;
    auto leg = subjects.AddLeg(subject_id, storage::Side::kRight);
    EXPECT_TRUE(leg.ok());
    leg_id = leg->id;
    storage::SessionDetails sd;
    sd.date = "2026-01-15";
    sd.accelerometer_placement = "shank, 28 cm below the knee";
    if (o.with_limits) {
      sd.threshold_ma = vs.threshold_ma;
      sd.max_tolerated_ma = vs.max_tolerated_ma;
    }
    auto session = storage::SessionRepository(*db).Create(subject_id, leg_id, sd);
    EXPECT_TRUE(session.ok()) << session.status().ToString();
    session_id = session->id;

    SimulatedBenchOptions bo;
    bo.time_scale = o.time_scale;
    bo.seed = 3;
    bo.on_control_step = [this](double t_s) {
      if (hook) hook(t_s);
    };
    bench = std::make_unique<SwappableSimulatedBench>(vs, bo);

    config.time_scale = o.time_scale;
    config.arm_watchdog = o.arm_watchdog;
    if (o.wall_clock_is_bench_time) config.wall_clock = [this] { return bench->Now_s(); };
    config.log = [this](std::string_view m) {
      std::lock_guard lock(log_mu);
      logs.emplace_back(m);
    };
    service = std::make_unique<RunService>(*db, *bench, hub, config);
  }
  ~Rig() {
    service.reset();
    db.reset();
    std::filesystem::remove_all(dir);
  }

  static Actor Make(storage::UserRepository& users, const char* name, storage::Role role,
                    Role service_role) {
    auto u = users.CreateUser(name, role);
    EXPECT_TRUE(u.ok()) << u.status().ToString();
    return Actor{u.ok() ? u->id : 0, name, service_role};
  }

  /// The plan the service will run (same context), to compare with.
  protocols::Plan PlanFor(const std::string& protocol, const protocols::ParameterValues& values) {
    auto context = LoadSessionContext(*db, session_id, bench->limits());
    EXPECT_TRUE(context.ok()) << context.status().ToString();
    auto plan = protocols::MakePlan(protocol, values, context->subject);
    EXPECT_TRUE(plan.ok()) << plan.status().ToString();
    return *plan;
  }

  std::vector<std::string> AuditActions() {
    storage::AuditQuery q;
    auto entries = storage::AuditLog(*db).List(q);
    EXPECT_TRUE(entries.ok());
    std::vector<storage::AuditEntry> sorted = *entries;
    std::sort(sorted.begin(), sorted.end(),
              [](const auto& a, const auto& b) { return a.id < b.id; });
    std::vector<std::string> out;
    for (const auto& e : sorted) out.push_back(e.entry.action);
    return out;
  }

  RigOptions options;
  std::filesystem::path dir;
  std::unique_ptr<storage::Database> db;
  Actor clinician, analyst, admin;
  VirtualSubject vs;
  std::int64_t subject_id = 0, leg_id = 0, session_id = 0;
  std::function<void(double)> hook;  // set before a run starts only
  std::unique_ptr<SwappableSimulatedBench> bench;
  SampleHub hub;
  RunServiceConfig config;
  std::unique_ptr<RunService> service;
  std::mutex log_mu;
  std::vector<std::string> logs;
};

/// What a subscriber saw of one run.
struct Stream {
  std::vector<HubItemPtr> items;
  std::map<int, std::size_t> samples_per_trial;
  std::uint64_t samples = 0;
  bool in_order = true;  // first_sample contiguous, t_s increasing within a trial
  bool ended = false;
  std::uint64_t dropped = 0;
};

Stream Read(Subscription& sub) {
  Stream s;
  std::uint64_t last_seq = 0;
  std::map<int, double> last_t;
  while (HubItemPtr item = sub.Next(kWait)) {
    if (item->seq <= last_seq && last_seq != 0) s.in_order = false;
    last_seq = item->seq;
    s.items.push_back(item);
    if (item->kind == HubItem::Kind::kSamples) {
      if (item->first_sample != s.samples) s.in_order = false;
      for (double t : item->samples.t_s) {
        const auto it = last_t.find(item->samples.trial);
        if (it != last_t.end() && !(t > it->second)) s.in_order = false;
        last_t[item->samples.trial] = t;
      }
      s.samples += item->samples.t_s.size();
      s.samples_per_trial[item->samples.trial] += item->samples.t_s.size();
    }
    if (item->kind == HubItem::Kind::kEnd) {
      s.ended = true;
      break;
    }
  }
  s.dropped = sub.dropped();
  return s;
}

/// Polls until the run is running (or over); a run is e-stopped while
/// running, not while still queued.
void WaitRunning(RunService& service, std::int64_t run_id) {
  const auto deadline = std::chrono::steady_clock::now() + kWait;
  while (std::chrono::steady_clock::now() < deadline) {
    auto v = service.Get(run_id);
    if (!v.ok() || v->state != RunState::kQueued) return;
    std::this_thread::sleep_for(1ms);
  }
}

const protocols::ParameterValues kShortTolerance = {
    {"settle_s", 0.2}, {"start_ma", 0.0}, {"rate_ma_per_s", 5.0}, {"ceiling_ma", 3.0}};

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
  const nlohmann::json j = RunViewToJson(*view);
  EXPECT_EQ(j.at("state"), "done");
  EXPECT_EQ(j.at("trial_ids").size(), plan.trials.size());
}

TEST(RunService, RapidProtocolStoresAParameterSetWhoseProvenanceTrialsExist) {
  Rig rig;
  const protocols::Plan plan = rig.PlanFor("rapid_parameterisation", {});
  ASSERT_TRUE(plan.rapid.has_value());
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
      view->trial_ids[static_cast<std::size_t>(plan.rapid->ramp_trial)],
      view->trial_ids[static_cast<std::size_t>(plan.rapid->active_trial)]};
  for (int k : plan.rapid->swing_trials)
    used.push_back(view->trial_ids[static_cast<std::size_t>(k)]);
  for (const auto& [hold, swing] : plan.rapid->release_trials)
    used.push_back(view->trial_ids[static_cast<std::size_t>(hold)]);
  std::sort(used.begin(), used.end());
  EXPECT_EQ(set->trial_ids, used);
  EXPECT_EQ(set->params.provenance.trial_ids, used);
  EXPECT_EQ(set->params.provenance.active_trial_id,
            view->trial_ids[static_cast<std::size_t>(plan.rapid->active_trial)]);
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

// Issue 16 §1: a tolerance test on a session with a recorded max tolerated
// amplitude ramps at most to it unless a clinician gives an explicit,
// audited ceiling above it.
TEST(RunService, ToleranceTestNeverGoesAboveTheRecordedMaxByDefault) {
  Rig rig;
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
  Rig rig({.with_limits = false});
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
}

// Issue 16 §2–§3 in process: a new RunService on the same database (a
// restart) closes the runs left open and latches a stored e-stop again.
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
}

}  // namespace
}  // namespace fesbench::server::services
