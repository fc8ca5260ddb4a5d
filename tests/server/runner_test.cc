// The protocol engine on the simulated bench (docs/PROTOCOLS.md; docs/SAFETY.md): every
// protocol runs to completion on a seeded virtual subject in accelerated
// time and records the thesis's trials; tolerance test; rapid
// parameterisation recovers the subject; e-stop, watchdog, cancel, one run
// at a time, model-gated stimulation.
#include "server/protocols/runner.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <map>
#include <mutex>
#include <numeric>

#include "api/parameter_set_json.h"
#include "api/run_outcome.h"
#include "model/identify_rapid.h"
#include "model/simulate.h"
#include "server/bench/simulated_bench.h"
#include "server/protocols/bench_owner.h"
#include "server/protocols/model_gate.h"
#include "server/protocols/rapid_identification.h"
#include "tests/server/runner_rig.h"
#include "tests/support/manual_clock.h"

namespace fesbench::server::protocols {
namespace {

using test::NoWatchdog;
using test::Rig;
using test::Rms;

VirtualSubject Subject(std::uint64_t seed) { return DrawVirtualSubject(seed); }

SubjectContext Context(const VirtualSubject& vs) { return test::WithKnownInertia(vs); }

// --- every protocol runs and records what the thesis describes ---------------

class EveryProtocol : public ::testing::TestWithParam<std::string> {};

TEST_P(EveryProtocol, RunsToCompletionAndRecordsThePlannedTrials) {
  Rig rig(7);
  const SubjectContext ctx = Context(rig.subject);
  ParameterValues values;
  // The tolerance test ramps to the recorded max (its default ceiling).
  if (GetParam() == "tolerance_test") values = {{"rate_ma_per_s", 2.0}};
  auto plan = MakePlan(GetParam(), values, ctx);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  ProtocolRunner runner(rig.safe, &rig.log, nullptr, NoWatchdog());
  const RunResult r = runner.Run(*plan, ctx);
  ASSERT_EQ(r.state, RunState::kDone) << r.reason;
  bool searches = false;  // rapid: the extension search ends at full extension
  for (const Step& st : plan->steps) searches = searches || st.end_below_angle_deg.has_value();
  if (searches) {
    EXPECT_LE(r.bench_duration_s, plan->duration_s() + 1e-6);
  } else {
    EXPECT_NEAR(r.bench_duration_s, plan->duration_s(), 1e-6);
  }
  ASSERT_EQ(r.trials.size(), plan->trials.size());
  for (std::size_t k = 0; k < r.trials.size(); ++k) {
    SCOPED_TRACE(plan->trials[k].name);
    const api::Trial& t = r.trials[k].trial;
    ASSERT_TRUE(api::ValidateTrial(t).ok()) << api::ValidateTrial(t).ToString();
    EXPECT_EQ(t.name, plan->trials[k].name);
    EXPECT_EQ(t.FindChannel("angle_deg")->unit, "deg");
    EXPECT_EQ(t.FindChannel("torque_nm")->unit, "N.m");
    EXPECT_EQ(t.FindChannel("stim_ma")->unit, "mA");
    ASSERT_NE(t.FindChannel("accel_m_s2"), nullptr);
    // 200 Hz, t_s from 0.
    const std::vector<double>& ts = *t.Values("t_s");
    EXPECT_DOUBLE_EQ(ts.front(), 0.0);
    EXPECT_NEAR(ts[1] - ts[0], 0.005, 1e-12);
    // The stimulation recorded is the planned envelope (durations, levels,
    // rests: protocol_test checks the envelopes against the thesis).
    const model::SampledSignal env = TrialEnvelope(*plan, static_cast<int>(k));
    const std::vector<double>& stim = *t.Values("stim_ma");
    // rapid: the random-binary levels rescaled between threshold and the
    // amplitude the extension search found (ApplySearchedAmplitude).
    double scale = 1.0, floor = 0.0;
    const AdaptiveAmplitude* adapt =
        plan->adaptive_amplitude ? &*plan->adaptive_amplitude : nullptr;
    if (adapt != nullptr && std::count(adapt->trials.begin(), adapt->trials.end(), int(k))) {
      floor = adapt->min_ma;
      scale = (r.values.at("rb_amplitude_ma") - floor) / (adapt->planned_ma - floor);
    }
    bool searched = false;
    for (const Step& st : plan->steps)
      searched = searched || (st.trial == static_cast<int>(k) && st.end_below_angle_deg);
    if (!plan->tolerance && !searched) {
      ASSERT_EQ(stim.size(), env.size());
      for (std::size_t i = 0; i < stim.size(); ++i) {
        const double u = env.values[i] > 0.0 ? floor + (env.values[i] - floor) * scale : 0.0;
        ASSERT_NEAR(stim[i], std::min(u, ctx.max_tolerated_ma), 1e-9) << "sample " << i;
      }
    } else if (searched) {
      // The search rises until full extension (or max), then the fall.
      ASSERT_LE(stim.size(), env.size());
      for (std::size_t i = 1; i < stim.size() && stim[i] > 0.0; ++i) {
        ASSERT_GE(stim[i], stim[i - 1]);
        ASSERT_LE(stim[i], ctx.max_tolerated_ma + 1e-9);
      }
    }
    // EMG at 1 kHz over the same span (§5.2.1 pre/post check).
    ASSERT_TRUE(t.emg.has_value());
    EXPECT_DOUBLE_EQ(t.emg->sample_rate_hz, 1000.0);
    EXPECT_NEAR(static_cast<double>(t.emg->num_samples()), 5.0 * stim.size(), 5.0);
    // One 50-sample torque offset before each stimulation segment.
    std::size_t offsets = 0;
    for (const Step& s : plan->steps)
      offsets += s.trial == static_cast<int>(k) && s.phase == StepPhase::kOffset;
    EXPECT_EQ(r.trials[k].offsets_nm.size(), offsets);
    const std::vector<double>& angle = *t.Values("angle_deg");
    if (plan->trials[k].mode == MotorMode::kLocked) {
      for (double a : angle) ASSERT_NEAR(a, 90.0, 3.0);  // locked at 90°
    } else if (plan->trials[k].mode == MotorMode::kPosition) {
      // The servo follows the trajectory.
      EXPECT_LT(Rms(angle, *t.Values("setpoint_deg")), 2.0);
    } else {
      const auto [lo, hi] = std::minmax_element(angle.begin(), angle.end());
      if (*std::max_element(stim.begin(), stim.end()) > 0.0) {
        EXPECT_GT(*hi - *lo, 5.0);  // it swung
      }
    }
  }
  // Nothing a protocol asked for was clamped.
  for (const SafetyEvent& e : r.safety_events) {
    EXPECT_NE(e.kind, SafetyEvent::Kind::kStimClamped) << e.detail;
  }
}

INSTANTIATE_TEST_SUITE_P(Catalog, EveryProtocol,
                         ::testing::Values("tolerance_test", "isometric_ramp_irc",
                                           "isometric_step_irc", "isometric_impulse_irc",
                                           "isometric_prediction", "passive_sequential",
                                           "passive_simultaneous", "free_swing_passive",
                                           "active_random_binary", "prediction_step",
                                           "prediction_ramp", "prediction_sine",
                                           "prediction_random_binary", "rapid_parameterisation"));

TEST(Runner, StepIrcRestsThirtySecondsBetweenBursts) {
  Rig rig(7);
  const SubjectContext ctx = Context(rig.subject);
  auto plan = MakePlan("isometric_step_irc", {}, ctx);
  ASSERT_TRUE(plan.ok());
  ProtocolRunner runner(rig.safe, &rig.log, nullptr, NoWatchdog());
  const RunResult r = runner.Run(*plan, ctx);
  ASSERT_EQ(r.state, RunState::kDone);
  const std::vector<double>& stim = *r.trials[0].trial.Values("stim_ma");
  const std::vector<double>& torque = *r.trials[0].trial.Values("torque_nm");
  // Burst starts and the torque of the last 0.5 s of each burst (§5.3.1).
  std::vector<std::size_t> starts;
  for (std::size_t i = 1; i < stim.size(); ++i) {
    if (stim[i] > 0.0 && stim[i - 1] == 0.0) starts.push_back(i);
  }
  ASSERT_EQ(starts.size(), 10u);
  double previous = -1.0;
  for (std::size_t k = 0; k < starts.size(); ++k) {
    if (k > 0) {
      EXPECT_EQ(starts[k] - starts[k - 1], 6600u);  // 3 s burst + 30 s rest
    }
    const double mean = std::accumulate(torque.begin() + static_cast<long>(starts[k] + 500),
                                        torque.begin() + static_cast<long>(starts[k] + 600), 0.0) /
                        100.0;
    if (k >= 2) {
      EXPECT_GT(mean, previous - 0.3);  // the IRC rises with level
    }
    previous = mean;
  }
  EXPECT_GT(previous, 5.0);  // torque at max (offset removed)
  // Offset removal: the torque before the first burst reads ≈ 0.
  EXPECT_NEAR(torque[starts[0]], 0.0, 0.3);
  EXPECT_NEAR(torque[starts[1] - 20], 0.0, 0.3);
}

// --- tolerance test ---------------------------------------------------------------

class StopAt : public RunObserver {
 public:
  StopAt(ProtocolRunner** runner, double stim_ma) : runner_(runner), stim_ma_(stim_ma) {}
  void OnSamples(const SampleBatch& b) override {
    if (!b.stim_ma.empty() && b.stim_ma.back() >= stim_ma_) (*runner_)->Stop();
  }
  void OnProgress(const Progress& p) override { last = p; }
  Progress last;

 private:
  ProtocolRunner** runner_;
  double stim_ma_;
};

TEST(Runner, ToleranceTestFindsThresholdAndStopsWhereTheClinicianStops) {
  Rig rig(7);
  SubjectContext ctx = Context(rig.subject);
  auto plan = MakePlan("tolerance_test", {}, ctx);
  ASSERT_TRUE(plan.ok());
  ProtocolRunner* ptr = nullptr;
  StopAt stop(&ptr, 38.0);
  ProtocolRunner runner(rig.safe, &rig.log, &stop, NoWatchdog());
  ptr = &runner;
  const RunResult r = runner.Run(*plan, ctx);
  ASSERT_EQ(r.state, RunState::kDone) << r.reason;
  ASSERT_TRUE(r.tolerance.has_value());
  const ToleranceResult& t = *r.tolerance;
  EXPECT_TRUE(t.stopped_by_clinician);
  EXPECT_NEAR(t.max_tolerated_ma, 38.0, 0.25);  // stopped within one 40-sample batch at 0.5 mA/s
  ASSERT_TRUE(t.threshold_ma.has_value());
  // The subject's IRC is 0 up to 21.9 mA and rises smoothly; the first
  // torque above the 0.5 N·m band comes a few mA above threshold.
  EXPECT_GE(*t.threshold_ma, rig.subject.threshold_ma);
  EXPECT_LE(*t.threshold_ma, rig.subject.threshold_ma + 5.0);
  EXPECT_GT(t.max_torque_nm, 6.0);
  EXPECT_TRUE(t.warnings.empty());
  EXPECT_LT(r.bench_duration_s, plan->duration_s());
  // The bench time reported at the end is the time run, not the plan's.
  EXPECT_DOUBLE_EQ(stop.last.fraction, 1.0);
  EXPECT_NEAR(stop.last.bench_total_s, r.bench_duration_s, 0.01);
  EXPECT_DOUBLE_EQ(stop.last.bench_elapsed_s, stop.last.bench_total_s);
  EXPECT_DOUBLE_EQ(stop.last.bench_planned_s, plan->duration_s());  // kept, by its own name
}

TEST(RunWire, ARunsPiecesCarryTheirUnitsInTheirKeys) {
  Rig rig(7);
  const SubjectContext ctx = Context(rig.subject);
  auto plan = MakePlan("tolerance_test", {{"ceiling_ma", 30.0}, {"rate_ma_per_s", 5.0}}, ctx);
  ASSERT_TRUE(plan.ok());
  ProtocolRunner runner(rig.safe, &rig.log, nullptr, NoWatchdog());
  const RunResult r = runner.Run(*plan, ctx);
  EXPECT_EQ(r.state, RunState::kDone);
  EXPECT_EQ(r.protocol, "tolerance_test");
  EXPECT_DOUBLE_EQ(r.parameters.at("ceiling_ma"), 30.0);
  ASSERT_EQ(r.trials.size(), 1u);
  ASSERT_TRUE(r.tolerance.has_value());
  EXPECT_NEAR(api::ToleranceResultToJson(*r.tolerance).at("max_tolerated_ma").get<double>(), 30.0,
              0.05);
  EXPECT_FALSE(r.parameter_set.has_value());
  SafetyEvent e{SafetyEvent::Kind::kStimClamped, 1.5, 120.0, 45.0, "limited"};
  const nlohmann::json ej = api::SafetyEventToJson(e);
  EXPECT_EQ(ej.at("kind"), "stim_clamped");
  EXPECT_DOUBLE_EQ(ej.at("requested").get<double>(), 120.0);
  e.requested = std::nan("");
  EXPECT_TRUE(api::SafetyEventToJson(e).at("requested").is_null());
  Progress p;
  p.fraction = 0.25;
  p.phase = StepPhase::kStimulate;
  EXPECT_EQ(api::ProgressToJson(p).at("phase"), "stimulate");
  SampleBatch b;
  b.t_s = {0.0, 0.005};
  b.angle_deg = {90.0, 90.1};
  EXPECT_EQ(api::SampleBatchToJson(b).at("angle_deg").size(), 2u);
}

TEST(Runner, ToleranceTestRunsToTheCeilingWithoutStop) {
  Rig rig(7);
  const SubjectContext ctx = Context(rig.subject);
  auto plan = MakePlan("tolerance_test", {{"ceiling_ma", 30.0}, {"rate_ma_per_s", 2.0}}, ctx);
  ASSERT_TRUE(plan.ok());
  ProtocolRunner runner(rig.safe, &rig.log, nullptr, NoWatchdog());
  const RunResult r = runner.Run(*plan, ctx);
  ASSERT_EQ(r.state, RunState::kDone);
  EXPECT_FALSE(r.tolerance->stopped_by_clinician);
  EXPECT_EQ(r.values.at("subject_signalled_limit"), 0.0);
  EXPECT_NEAR(r.tolerance->max_tolerated_ma, 30.0, 0.05);
  EXPECT_FALSE(r.tolerance->warnings.empty());  // < 6 N·m at 30 mA for this subject
}

TEST(Runner, ToleranceTestLeftRunningEndsWhereTheSubjectSignalsTheLimit) {
  // A first session (no recorded max: the 60 mA ceiling stands alone) and a
  // clinician who never stops: the simulated subject signals its own limit.
  Rig rig(7);
  SubjectContext ctx = Context(rig.subject);
  ctx.max_tolerated_ma = 100.0;
  ctx.max_tolerated_recorded = false;
  auto plan = MakePlan("tolerance_test", {{"rate_ma_per_s", 5.0}}, ctx);
  ASSERT_TRUE(plan.ok());
  ASSERT_LT(rig.subject.max_tolerated_ma, 60.0);
  ProtocolRunner runner(rig.safe, &rig.log, nullptr, NoWatchdog());
  const RunResult r = runner.Run(*plan, ctx);
  ASSERT_EQ(r.state, RunState::kDone) << r.reason;
  EXPECT_FALSE(r.tolerance->stopped_by_clinician);
  EXPECT_EQ(r.values.at("subject_signalled_limit"), 1.0);
  // The first pulse at or above the limit, seen at the next 5 ms sample:
  // pulses 30 ms apart at 5 mA/s put it at most 0.2 mA above.
  EXPECT_GE(r.tolerance->max_tolerated_ma, rig.subject.max_tolerated_ma);
  EXPECT_LT(r.tolerance->max_tolerated_ma, rig.subject.max_tolerated_ma + 0.25);
  EXPECT_LT(r.bench_duration_s, plan->duration_s());
}

// --- e-stop, watchdog, cancel, one run at a time, model gate -----------------------------

// --- one pulse-timing rule and the stimulator read-back -----------------------

// Every pulse of a trial is on the trial's grid k/f or a single pulse at an
// envelope sample; the pulses the runner stores are those PulsesFromEnvelope
// makes of the trial's stim_ma channel and of its stim_delivered_ma channel.
void ExpectTrialFollowsThePulseRule(const api::Trial& t, bool expect_singles) {
  ASSERT_TRUE(t.pulses.has_value()) << *t.name;
  const model::PulseTrain stored = t.pulses->Train();
  ASSERT_FALSE(stored.empty()) << *t.name;
  EXPECT_EQ(t.pulses->pulse_rate_hz, 33.0);
  EXPECT_EQ(t.pulses->pulse_width_us, 300.0);
  std::size_t singles = 0;
  for (const model::Pulse& p : stored) {
    const double k = p.t_s * 33.0;
    if (std::abs(k - std::round(k)) > 1e-7) ++singles;
  }
  EXPECT_EQ(singles > 0, expect_singles) << *t.name << ": " << singles << " off-grid pulses";
  for (const char* channel : {"stim_ma", "stim_delivered_ma"}) {
    const std::vector<double>* v = t.Values(channel);
    ASSERT_NE(v, nullptr) << channel;
    const model::PulseTrain rebuilt =
        model::PulsesFromEnvelope(model::SampledSignal{t.sample_rate_hz, 0.0, *v}, 33.0);
    ASSERT_EQ(rebuilt.size(), stored.size()) << *t.name << " " << channel;
    for (std::size_t i = 0; i < stored.size(); ++i) {
      EXPECT_NEAR(rebuilt[i].t_s, stored[i].t_s, 1e-9) << *t.name << " " << channel << " " << i;
      EXPECT_NEAR(rebuilt[i].stim_ma, stored[i].stim_ma, 1e-12) << channel << " " << i;
    }
  }
}

TEST(Runner, TrialsStoreTheDeliveredPulsesOnTheTrialsGrid) {
  for (const char* protocol : {"prediction_random_binary", "isometric_ramp_irc"}) {
    Rig rig(7);
    const SubjectContext ctx = Context(rig.subject);
    auto plan = MakePlan(protocol, {}, ctx);
    ASSERT_TRUE(plan.ok()) << plan.status().ToString();
    ProtocolRunner runner(rig.safe, &rig.log, nullptr, NoWatchdog());
    const RunResult r = runner.Run(*plan, ctx);
    ASSERT_EQ(r.state, RunState::kDone) << r.reason;
    std::size_t stored = 0;
    for (const RecordedTrial& rt : r.trials) {
      // isometric_ramp_irc has impulses off the trial's grid: single pulses.
      ExpectTrialFollowsThePulseRule(rt.trial, std::string(protocol) == "isometric_ramp_irc");
      stored += rt.trial.pulses->size();
    }
    // Every pulse the leg got during the run is in a trial.
    EXPECT_EQ(stored, rig.bench.DeliveredPulses().size()) << protocol;
  }
}

// Stimulator read-back (docs/SAFETY.md): a command above the limit injected below the runner — a
// faulty caller of the safety layer, in the middle of a run — never reaches
// the leg, and the trial's read-back shows the clamp (the runner's own
// stim_ma channel does not see the injection at all).
TEST(Runner, OverLimitCommandInjectedBelowTheRunnerNeverReachesTheLeg) {
  SafeBench* safe = nullptr;
  SimulatedBenchOptions o;
  o.on_control_step = [&](double t_s) {
    // Inside the step's stimulation (lead 0.5 s + offset), while the runner
    // holds its amplitude and so does not overwrite the injected one.
    if (safe != nullptr && t_s > 1.5 && t_s < 1.502) {
      safe->SetStimAmplitude(150.0);
      safe->TriggerPulse(150.0);
    }
  };
  Rig rig(7, o);
  safe = &rig.safe;
  const SubjectContext ctx = Context(rig.subject);
  const double limit = ctx.max_tolerated_ma;
  auto plan = MakePlan("prediction_step", {}, ctx);
  ASSERT_TRUE(plan.ok());
  ProtocolRunner runner(rig.safe, &rig.log, nullptr, NoWatchdog());
  const RunResult r = runner.Run(*plan, ctx);
  ASSERT_EQ(r.state, RunState::kDone) << r.reason;
  ASSERT_EQ(r.trials.size(), 1u);
  const api::Trial& t = r.trials[0].trial;
  const std::vector<double>& commanded = *t.Values("stim_ma");
  const std::vector<double>& delivered = *t.Values("stim_delivered_ma");
  const double max_commanded = *std::max_element(commanded.begin(), commanded.end());
  const double max_delivered = *std::max_element(delivered.begin(), delivered.end());
  EXPECT_LT(max_commanded, limit - 1.0);   // the plan's own level
  EXPECT_DOUBLE_EQ(max_delivered, limit);  // the injection, clamped
  ASSERT_TRUE(t.pulses.has_value());
  std::size_t at_limit = 0;
  for (double u : t.pulses->stim_ma) {
    EXPECT_LE(u, limit);
    at_limit += u == limit ? 1 : 0;
  }
  EXPECT_GT(at_limit, 1u);  // a single pulse and the train it set, both clamped
  // The leg itself (the bench's truth) never got more.
  for (const model::Pulse& p : rig.bench.DeliveredPulses()) EXPECT_LE(p.stim_ma, limit);
  std::size_t clamps = 0;
  for (const SafetyEvent& e : r.safety_events) {
    if (e.kind == SafetyEvent::Kind::kStimClamped && e.requested == 150.0) ++clamps;
  }
  EXPECT_GE(clamps, 2u);
  EXPECT_FALSE(rig.safe.estopped());  // the clamp held: the read-back found nothing to stop
}

TEST(Runner, EStopCutsStimulationWithinOneControlPeriodAndLatches) {
  SafeBench* safe = nullptr;
  std::atomic<double> estop_at{-1.0};
  SimulatedBenchOptions o;
  o.on_control_step = [&](double t_s) {
    // Mid-step of the prediction, while stimulation is on (0.5–3.5 s + lead).
    if (safe != nullptr && estop_at.load() < 0.0 && t_s >= 4.0) {
      estop_at.store(t_s);
      safe->EStop("bench button");
    }
  };
  Rig rig(7, o);
  safe = &rig.safe;
  const SubjectContext ctx = Context(rig.subject);
  auto plan = MakePlan("prediction_step", {}, ctx);
  ASSERT_TRUE(plan.ok());
  ProtocolRunner runner(rig.safe, &rig.log, nullptr, NoWatchdog());
  const RunResult r = runner.Run(*plan, ctx);
  EXPECT_EQ(r.state, RunState::kAborted);
  EXPECT_EQ(r.reason, "e-stop");
  const double t_stop = estop_at.load();
  ASSERT_GT(t_stop, 0.0);
  const model::PulseTrain pulses = rig.bench.DeliveredPulses();
  ASSERT_FALSE(pulses.empty());
  EXPECT_LT(pulses.front().t_s, t_stop);  // it was stimulating
  for (const model::Pulse& p : pulses) EXPECT_LE(p.t_s, t_stop + 1e-3) << "pulse after the e-stop";
  // Motor disabled: only the unpowered gearbox drag acts, no servo torque.
  const LegTruth truth = rig.bench.Truth();
  EXPECT_LE(std::abs(truth.motor_torque_nm), 1.0 + 0.02 * std::abs(truth.velocity_deg_s) + 1e-9);
  ASSERT_FALSE(r.trials.empty());
  EXPECT_FALSE(r.trials.back().complete);
  bool logged = false;
  for (const SafetyEvent& e : r.safety_events) logged |= e.kind == SafetyEvent::Kind::kEStop;
  EXPECT_TRUE(logged);
  // Latched: a new run is refused until cleared.
  ProtocolRunner again(rig.safe, &rig.log, nullptr, NoWatchdog());
  EXPECT_EQ(again.Run(*plan, ctx).state, RunState::kFailed);
  rig.safe.ClearEStop("clinician");
  ProtocolRunner third(rig.safe, &rig.log, nullptr, NoWatchdog());
  EXPECT_EQ(third.Run(*plan, ctx).state, RunState::kDone);
}

TEST(Runner, WatchdogStopsTheRunWhenHeartbeatsStop) {
  // Wall clock = bench time (the bench is paced at real time in effect).
  ::fesbench::testing::ManualClock wall;
  std::atomic<bool> beating{true};
  SimulatedBenchOptions o;
  BenchOwner* owner = nullptr;
  o.on_control_step = [&](double t_s) {
    wall.Set(t_s);
    // The client heart-beats every 0.2 s until 3 s, then goes silent.
    if (owner != nullptr && beating.load() && std::fmod(t_s + 1e-9, 0.2) < 1e-6) {
      if (t_s < 3.0) {
        owner->Heartbeat();
      } else {
        beating.store(false);
      }
    }
  };
  const VirtualSubject vs = Subject(7);
  const std::unique_ptr<SimulatedBench> bench_owner = SimulatedBench::Create(vs, o).value();
  SimulatedBench& bench = *bench_owner;
  BenchOwnerOptions bo;
  bo.clock = &wall;
  BenchOwner own(bench, bo);
  owner = &own;
  StartRequest req{"prediction_ramp", {}, Context(vs), "web"};
  ASSERT_TRUE(own.Start(req).ok());
  const std::optional<RunResult> r = own.Wait();
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->state, RunState::kAborted);
  EXPECT_NE(r->reason.find("watchdog"), std::string::npos) << r->reason;
  // Last heartbeat at 2.8 s, timeout 1 s: stopped at ≈ 3.8 s.
  EXPECT_NEAR(bench.Now_s(), 3.8, 0.01);
  double fired_s = -1.0;
  for (const SafetyEvent& e : r->safety_events) {
    if (e.kind == SafetyEvent::Kind::kWatchdog) fired_s = e.t_s;
  }
  ASSERT_GT(fired_s, 0.0);
  const model::PulseTrain pulses = bench.DeliveredPulses();
  ASSERT_FALSE(pulses.empty());
  EXPECT_LE(pulses.back().t_s, fired_s + 1e-3);  // stimulation stopped at once
  bool logged = fired_s > 0.0;
  EXPECT_TRUE(logged);
}

// Blocks the run at its first step until released.
class Gate : public RunObserver {
 public:
  void OnStep(std::size_t, const Step&) override {
    std::unique_lock lock(mu_);
    entered_ = true;
    cv_.notify_all();
    cv_.wait(lock, [&] { return open_; });
  }
  void WaitEntered() {
    std::unique_lock lock(mu_);
    cv_.wait(lock, [&] { return entered_; });
  }
  void Open() {
    std::lock_guard lock(mu_);
    open_ = true;
    cv_.notify_all();
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  bool entered_ = false, open_ = false;
};

TEST(BenchOwner, OneRunAtATimeAndCancelFromAnotherThread) {
  const VirtualSubject vs = Subject(7);
  const std::unique_ptr<SimulatedBench> bench_owner = SimulatedBench::Create(vs).value();
  SimulatedBench& bench = *bench_owner;
  BenchOwnerOptions bo;
  bo.runner.arm_watchdog = false;
  BenchOwner own(bench, bo);
  auto gate = std::make_shared<Gate>();
  StartRequest req{"isometric_step_irc", {}, Context(vs), "alice"};
  ASSERT_TRUE(own.Start(req, gate).ok());
  gate->WaitEntered();
  EXPECT_TRUE(own.busy());
  EXPECT_EQ(own.owner(), "alice");
  StartRequest other{"prediction_step", {}, Context(vs), "bob"};
  const api::Status second = own.Start(other);
  EXPECT_EQ(second.code(), api::ErrorCode::kConflict);
  EXPECT_NE(second.message().find("alice"), std::string::npos);
  EXPECT_TRUE(own.Cancel("clinician pressed stop").ok());
  gate->Open();
  const std::optional<RunResult> r = own.Wait();
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->state, RunState::kAborted);
  EXPECT_EQ(r->reason, "clinician pressed stop");
  EXPECT_FALSE(own.busy());
  EXPECT_EQ(own.Cancel().code(), api::ErrorCode::kNotFound);
  // Free again: the other client's run goes through.
  ASSERT_TRUE(own.Start(other).ok());
  EXPECT_EQ(own.Wait()->state, RunState::kDone);
}

TEST(BenchOwner, RefusesBadRequestsAndLatchedEStop) {
  const VirtualSubject vs = Subject(7);
  const std::unique_ptr<SimulatedBench> bench_owner = SimulatedBench::Create(vs).value();
  SimulatedBench& bench = *bench_owner;
  BenchOwner own(bench);
  StartRequest bad{"isometric_step_irc", {{"rest_s", 3.0}}, Context(vs), "alice"};
  const api::Status st = own.Start(bad);
  EXPECT_EQ(st.code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(st.field(), "parameters.rest_s");
  EXPECT_EQ(own.Start({"nope", {}, Context(vs), "a"}).code(), api::ErrorCode::kNotFound);
  own.EStop("dds");
  EXPECT_EQ(own.Start({"prediction_step", {}, Context(vs), "a"}).code(), api::ErrorCode::kConflict);
  EXPECT_TRUE(own.ClearEStop("web").ok());
  EXPECT_FALSE(own.safe_bench().estopped());
}

TEST(ModelGate, RefusesOnlyAFastArrivalAtAStopAndNamesIt) {
  SubjectContext ctx;
  ctx.threshold_ma = 20.0;
  ctx.max_tolerated_ma = 45.0;
  ctx.min_angle_deg = 15.0;
  ctx.max_angle_deg = 108.0;
  ctx.parameter_set = model::ExampleParameterSet();
  ctx.parameter_set_id = 4;
  const model::JointLimits stops{ctx.min_angle_deg, ctx.max_angle_deg};
  // A sane input: a gentle ramp extends the knee without reaching a stop.
  auto plan = MakePlan("prediction_ramp", {{"max_ma", 26.0}}, ctx);
  ASSERT_TRUE(plan.ok());
  auto p = PredictPlanSwing(*plan, *ctx.parameter_set, stops, 33.0);
  ASSERT_TRUE(p.ok()) << p.status().ToString();
  EXPECT_LT(p->min_angle_deg, p->start_angle_deg - 10.0);  // the ramp extends the knee
  EXPECT_GT(p->min_angle_deg, ctx.min_angle_deg);
  EXPECT_TRUE(p->impacts.empty());
  EXPECT_TRUE(CheckModelGate(*plan, ctx).ok());
  // The start is the passive rest angle, as in POST /predictions.
  EXPECT_NEAR(p->start_angle_deg, FreeSwingStartAngleDeg(*ctx.parameter_set), 1e-12);

  // A step at the subject's max drives this leg hard into the extension stop:
  // the same simulation without stops goes past 15° (so the stop is real).
  auto step = MakePlan("prediction_step", {}, ctx);
  ASSERT_TRUE(step.ok());
  auto hit = PredictPlanSwing(*step, *ctx.parameter_set, stops, 33.0);
  ASSERT_TRUE(hit.ok()) << hit.status().ToString();
  ASSERT_FALSE(hit->impacts.empty());
  const StopImpact& first = hit->impacts.front();
  EXPECT_TRUE(first.extension);
  EXPECT_DOUBLE_EQ(first.stop_deg, 15.0);
  EXPECT_GT(first.speed_deg_s, 90.0);
  ASSERT_TRUE(first.onset_s.has_value());
  EXPECT_LT(*first.onset_s, first.t_s);
  auto free = PredictPlanSwing(*step, *ctx.parameter_set, model::JointLimits{0.1, 179.9}, 33.0);
  ASSERT_TRUE(free.ok());
  EXPECT_LT(free->min_angle_deg, 15.0);
  const api::Status refused = CheckModelGate(*step, ctx, 33.0, 90.0);
  EXPECT_EQ(refused.code(), api::ErrorCode::kFailedPrecondition);
  const std::string m = refused.message();
  EXPECT_NE(m.find("parameter set 4"), std::string::npos) << m;
  EXPECT_NE(m.find("the stimulation from"), std::string::npos) << m;
  EXPECT_NE(m.find("extension stop (15°)"), std::string::npos) << m;
  EXPECT_NE(m.find("deg/s"), std::string::npos) << m;
  EXPECT_EQ(m.find("cannot simulate"), std::string::npos) << m;
  // A bench whose stops take that speed lets it run.
  EXPECT_TRUE(CheckModelGate(*step, ctx, 33.0, first.speed_deg_s * 1.01 + 1000.0).ok());

  // A set that cannot simulate the input (RK4 unstable with a vanishing
  // inertia) is reported as such, not as a range-of-motion refusal.
  SubjectContext diverging = ctx;
  diverging.parameter_set->passive.inertia_kgm2 = 1e-7;
  const api::Status unusable = CheckModelGate(*plan, diverging);
  EXPECT_EQ(unusable.code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_EQ(unusable.message().rfind("parameter set 4 cannot simulate this input: ", 0), 0u)
      << unusable.message();

  // Non-prediction protocols and legs without a parameter set are not gated.
  auto iso = MakePlan("isometric_ramp_irc", {}, ctx);
  ASSERT_TRUE(iso.ok());
  SubjectContext tiny = ctx;
  tiny.min_angle_deg = 89.0;
  tiny.max_angle_deg = 91.0;
  EXPECT_TRUE(CheckModelGate(*iso, tiny).ok());
  SubjectContext none = ctx;
  none.parameter_set.reset();
  EXPECT_TRUE(CheckModelGate(*step, none).ok());
  // The owner applies the gate, with the bench's limit, before touching the
  // bench: the step at max would drive this model's knee into the 15° stop
  // faster than a bench that allows 90 deg/s.
  const VirtualSubject vs = Subject(7);
  SimulatedBenchOptions strict;
  strict.limits.max_stop_impact_deg_s = 90.0;
  const std::unique_ptr<SimulatedBench> bench_owner = SimulatedBench::Create(vs, strict).value();
  SimulatedBench& bench = *bench_owner;
  BenchOwner own(bench);
  const api::Status st = own.Start({"prediction_step", {}, ctx, "a"});
  EXPECT_EQ(st.code(), api::ErrorCode::kFailedPrecondition) << st.ToString();
  EXPECT_FALSE(own.busy());
  EXPECT_TRUE(bench.DeliveredPulses().empty());
}

class Recorder : public RunObserver {
 public:
  void OnStateChanged(RunState s, const std::string&) override { states.push_back(s); }
  void OnProgress(const Progress& p) override { progress.push_back(p); }
  void OnSamples(const SampleBatch& b) override { samples += b.t_s.size(); }
  void OnTrial(const RecordedTrial&) override { ++trials; }
  void OnFinished(const RunResult&) override { ++finished; }
  std::vector<RunState> states;
  std::vector<Progress> progress;
  std::size_t samples = 0;
  int trials = 0, finished = 0;
};

TEST(Runner, ReportsStatesProgressWithEtaSamplesAndTrials) {
  Rig rig(7);
  const SubjectContext ctx = Context(rig.subject);
  auto plan = MakePlan("prediction_sine", {}, ctx);
  ASSERT_TRUE(plan.ok());
  Recorder obs;
  RunnerOptions o = NoWatchdog();
  o.time_scale = 2.0;  // ETA = bench time left / 2
  ProtocolRunner runner(rig.safe, &rig.log, &obs, o);
  const RunResult r = runner.Run(*plan, ctx);
  ASSERT_EQ(r.state, RunState::kDone);
  EXPECT_EQ(obs.states, (std::vector<RunState>{RunState::kRunning, RunState::kDone}));
  ASSERT_GT(obs.progress.size(), 50u);
  for (std::size_t i = 1; i < obs.progress.size(); ++i) {
    EXPECT_GE(obs.progress[i].fraction, obs.progress[i - 1].fraction);
  }
  const Progress& mid = obs.progress[obs.progress.size() / 2];
  EXPECT_NEAR(mid.eta_s, (mid.bench_total_s - mid.bench_elapsed_s) / 2.0, 1e-9);
  EXPECT_DOUBLE_EQ(obs.progress.back().fraction, 1.0);
  EXPECT_EQ(obs.samples, r.trials[0].trial.num_samples());
  EXPECT_EQ(obs.trials, 1);
  EXPECT_EQ(obs.finished, 1);
  // One plan per runner.
  const double t_before = rig.bench.Now_s();
  const RunResult again = runner.Run(*plan, ctx);
  EXPECT_EQ(again.state, RunState::kFailed);
  EXPECT_EQ(rig.bench.Now_s(), t_before);
}

TEST(Runner, CancelBeforeStartAbortsAtOnce) {
  Rig rig(7);
  const SubjectContext ctx = Context(rig.subject);
  auto plan = MakePlan("prediction_step", {}, ctx);
  ASSERT_TRUE(plan.ok());
  ProtocolRunner runner(rig.safe, &rig.log, nullptr, NoWatchdog());
  runner.Cancel("changed my mind");
  const RunResult r = runner.Run(*plan, ctx);
  EXPECT_EQ(r.state, RunState::kAborted);
  EXPECT_EQ(r.reason, "changed my mind");
  EXPECT_LE(r.bench_duration_s, 1e-3);
  EXPECT_TRUE(rig.bench.DeliveredPulses().empty());
}

}  // namespace
}  // namespace fesbench::server::protocols
