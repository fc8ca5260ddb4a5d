#include "server/bench/simulated_bench.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <thread>
#include <vector>

#include "model/evaluation.h"
#include "model/parameter_set.h"
#include "model/signal.h"
#include "model/simulate.h"
#include "model/stimulus_generators.h"
#include "model/units.h"
#include "server/bench/virtual_subject.h"
#include "tests/support/manual_clock.h"

namespace fesbench::server {
namespace {

constexpr double kLsb = 0.0381;

VirtualSubject ExampleSubject(const Fidelity& fidelity) {
  VirtualSubject s;
  s.truth = model::ExampleParameterSet();
  s.threshold_ma = 20.0;
  s.max_tolerated_ma = 45.0;
  s.fidelity = fidelity;
  return s;
}

SimulatedBenchOptions Options(double angle_deg, MotorMode mode, std::uint64_t seed = 1) {
  SimulatedBenchOptions o;
  o.initial_angle_deg = angle_deg;
  o.initial_setpoint_deg = angle_deg;
  o.initial_mode = mode;
  o.seed = seed;
  return o;
}

// Drives the bench with a 200 Hz envelope the way the protocol runner does
// (docs/MODEL.md, pulse timing): set the amplitude at sample i, read, advance to sample
// i + 1; a run too short to hold a grid time of the pulse clock (which runs
// from the bench's start here) goes out as one TriggerPulse at its start.
std::vector<SensorFrame> Drive(SimulatedBench& bench, const model::SampledSignal& env) {
  std::vector<SensorFrame> frames;
  std::size_t single_end = 0;
  for (std::size_t i = 0; i < env.size(); ++i) {
    const double u = env.values[i];
    if (u > 0.0 && (i == 0 || env.values[i - 1] == 0.0)) {
      std::size_t j = i;
      while (j < env.size() && env.values[j] > 0.0) ++j;
      if (!model::FirstGridTimeIn(env.TimeAt(i), env.TimeAt(j), bench.limits().pulse_rate_hz)) {
        bench.TriggerPulse(u);
        single_end = j;
      }
    }
    bench.SetStimAmplitude(i < single_end ? 0.0 : u);
    frames.push_back(bench.ReadSensors());
    bench.AdvanceTo(env.TimeAt(i + 1));
  }
  return frames;
}

// Bench and model deliver the same pulses for the same envelope.
void ExpectSamePulses(const model::PulseTrain& bench, const model::PulseTrain& model) {
  ASSERT_EQ(bench.size(), model.size());
  for (std::size_t i = 0; i < bench.size(); ++i) {
    EXPECT_NEAR(bench[i].t_s, model[i].t_s, 1e-9) << "pulse " << i;
    EXPECT_EQ(bench[i].stim_ma, model[i].stim_ma) << "pulse " << i;
  }
}

model::SampledSignal Burst(double lead_s, double on_s, double tail_s, double ma) {
  model::SampledSignal s;
  const auto n = [](double d) { return static_cast<std::size_t>(std::llround(d * 200.0)); };
  s.values.assign(n(lead_s), 0.0);
  s.values.insert(s.values.end(), n(on_s), ma);
  s.values.insert(s.values.end(), n(tail_s), 0.0);
  return s;
}

double MeanTorque(const std::vector<SensorFrame>& f, double t0, double t1) {
  double sum = 0.0;
  int n = 0;
  for (const auto& s : f) {
    if (s.t_s >= t0 - 1e-9 && s.t_s < t1 - 1e-9) {
      sum += s.torque_nm;
      ++n;
    }
  }
  return sum / n;
}

// --- the anchor: fidelity off = the model library's simulator ----------------

TEST(SimulatedBench, FreeSwingWithFidelityOffMatchesModelSimulator) {
  const VirtualSubject subject = ExampleSubject(Fidelity::Off());
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(subject, Options(90.0, MotorMode::kDecoupled)).value();
  SimulatedBench& bench = *bench_owner;
  const model::SampledSignal env = Burst(0.5, 1.0, 2.5, 28.0);
  const std::vector<SensorFrame> frames = Drive(bench, env);

  model::SimulationOptions so;
  so.duration_s = env.EndTime();
  so.initial_angle_deg = 90.0;
  const model::SimulationResult ref =
      model::SimulateFreeSwing(subject.truth, model::PulsesFromEnvelope(env, 33.0), so);
  ASSERT_EQ(ref.size(), frames.size());
  ExpectSamePulses(bench.DeliveredPulses(), model::PulsesFromEnvelope(env, 33.0));
  double max_err = 0.0, min_angle = 1e9;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    max_err = std::max(max_err, std::abs(frames[i].angle_deg - ref.angle_deg[i]));
    min_angle = std::min(min_angle, ref.angle_deg[i]);
  }
  EXPECT_LT(min_angle, 70.0);  // the leg really moved
  EXPECT_GT(min_angle, 12.0);  // and stayed off the stops (no stops in the model)
  EXPECT_LT(max_err, 0.05);
}

// One pulse-timing rule (docs/MODEL.md). A 10 s random-binary free swing on the
// bench (physics = the model's with fidelity off) against the model fed the
// same pulses: the closed loop agrees to ~1e-4°. The pulses restarted at
// each rise of the stimulation (the old rule) miss by degrees.
model::PulseTrain RestartAtEachRise(const model::SampledSignal& env, double rate_hz) {
  model::PulseTrain out;
  for (std::size_t i = 0; i < env.size();) {
    if (env.values[i] == 0.0) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < env.size() && env.values[j] != 0.0) ++j;
    for (int m = 0;; ++m) {
      const double t = env.TimeAt(i) + m / rate_hz;
      if (t >= env.TimeAt(j) - 1e-12) break;
      out.push_back({t, env.HoldAt(t)});
    }
    i = j;
  }
  return out;
}

TEST(SimulatedBench, RandomBinaryFreeSwingAgreesWithTheModelOnTheSamePulses) {
  const VirtualSubject subject = ExampleSubject(Fidelity::Off());
  const double rest_deg = model::PassiveRestAngle(subject.truth.passive);
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(subject, Options(rest_deg, MotorMode::kDecoupled)).value();
  SimulatedBench& bench = *bench_owner;
  const model::SampledSignal env = model::MakeStimulus(
      "random_binary_sparse", {{"amplitude_ma", 24.0}, {"duration_s", 10.0}, {"seed", 3.0}});
  const std::vector<SensorFrame> frames = Drive(bench, env);
  const model::PulseTrain delivered = bench.DeliveredPulses();
  ExpectSamePulses(delivered, model::PulsesFromEnvelope(env, 33.0));

  model::SimulationOptions so;
  so.duration_s = env.EndTime();
  so.initial_angle_deg = rest_deg;
  const auto rms_vs_bench = [&](const model::PulseTrain& pulses, double* max_abs) {
    const model::SimulationResult sim = model::SimulateFreeSwing(subject.truth, pulses, so);
    EXPECT_EQ(sim.size(), frames.size());
    double sum = 0.0;
    for (std::size_t i = 0; i < frames.size(); ++i) {
      const double d = frames[i].angle_deg - sim.angle_deg[i];
      sum += d * d;
      if (max_abs != nullptr) *max_abs = std::max(*max_abs, std::abs(d));
    }
    return std::sqrt(sum / static_cast<double>(frames.size()));
  };
  double max_abs = 0.0;
  const double rms = rms_vs_bench(delivered, &max_abs);
  const double rms_restart = rms_vs_bench(RestartAtEachRise(env, 33.0), nullptr);
  double lo = 1e9, hi = -1e9;
  for (const SensorFrame& f : frames) {
    lo = std::min(lo, f.angle_deg);
    hi = std::max(hi, f.angle_deg);
  }
  std::cout << "random-binary free swing " << lo << "–" << hi << "°: bench vs model on the "
            << "stored pulses RMS " << rms << "° (max " << max_abs << "°); vs pulses restarted "
            << "at each rise RMS " << rms_restart << "°\n";
  EXPECT_LT(hi - lo, 100.0);
  EXPECT_GT(hi - lo, 30.0);  // a real swing
  EXPECT_GT(lo, 12.0);       // off the stops (the model here has none)
  EXPECT_LT(rms, 2e-4);
  EXPECT_LT(max_abs, 1e-3);
  EXPECT_GT(rms_restart, 100.0 * rms);  // the grid matters
}

TEST(SimulatedBench, IsometricWithFidelityOffMatchesModelSimulator) {
  const VirtualSubject subject = ExampleSubject(Fidelity::Off());
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(subject, Options(90.0, MotorMode::kLocked)).value();
  SimulatedBench& bench = *bench_owner;
  model::SampledSignal env = Burst(0.3, 1.5, 1.2, 40.0);
  env.values[static_cast<std::size_t>(2.6 * 200)] = 45.0;  // a single twitch
  const std::vector<SensorFrame> frames = Drive(bench, env);

  model::SimulationOptions so;
  so.duration_s = env.EndTime();
  const model::SimulationResult ref =
      model::SimulateIsometric(subject.truth, model::PulsesFromEnvelope(env, 33.0), 90.0, so);
  ASSERT_EQ(ref.size(), frames.size());
  ExpectSamePulses(bench.DeliveredPulses(), model::PulsesFromEnvelope(env, 33.0));
  double max_err = 0.0, max_torque = 0.0;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    max_err = std::max(max_err, std::abs(frames[i].torque_nm - ref.torque_nm[i]));
    max_torque = std::max(max_torque, ref.torque_nm[i]);
    EXPECT_EQ(frames[i].angle_deg, 90.0);
  }
  EXPECT_GT(max_torque, 20.0);
  EXPECT_LE(max_err, kLsb / 2 + 1e-6);  // the quantisation only
}

// --- isometric steady state, fatigue, potentiation, SE --------------------------

TEST(SimulatedBench, SteadyIsometricTorqueAtMaxStimulation) {
  Fidelity fid = Fidelity::Default();
  fid.fatigue_rate_per_s = 0.0;
  fid.potentiation_max = 0.0;
  const VirtualSubject subject = ExampleSubject(fid);
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(subject, Options(90.0, MotorMode::kLocked)).value();
  SimulatedBench& bench = *bench_owner;
  const std::vector<SensorFrame> f = Drive(bench, Burst(1.0, 3.0, 0.5, 45.0));
  const double rest = MeanTorque(f, 0.5, 1.0);
  const double steady = MeanTorque(f, 3.5, 4.0);
  const double passive =
      subject.truth.passive.torque_angle(90.0) + subject.truth.passive.torque_velocity(0.0);
  EXPECT_NEAR(rest, passive, 0.03);
  const double expected = SteadyIsometricActiveTorqueNm(subject.truth, 45.0, 90.0);
  EXPECT_NEAR(expected, 40.0, 1e-9);  // τ_scale · f_ata(90) · f_atv(0) · R(45)
  // SE shifts θ_ce by τ/K_se ≈ 1.1° along f_ata: within 3 %.
  EXPECT_NEAR(steady - rest, expected, 0.03 * expected);
}

TEST(SimulatedBench, FatigueLowersTorqueAndRestRecoversIt) {
  const VirtualSubject subject = ExampleSubject(Fidelity::Default());
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(subject, Options(90.0, MotorMode::kLocked)).value();
  SimulatedBench& bench = *bench_owner;
  model::SampledSignal env = Burst(0.5, 20.0, 60.0, 45.0);
  const model::SampledSignal again = Burst(0.0, 3.0, 0.5, 45.0);
  env.values.insert(env.values.end(), again.values.begin(), again.values.end());
  const std::vector<SensorFrame> f = Drive(bench, env);
  const double rest = MeanTorque(f, 0.0, 0.5);
  const double early = MeanTorque(f, 2.0, 3.0) - rest;
  const double late = MeanTorque(f, 19.5, 20.5) - rest;
  const double recovered = MeanTorque(f, 82.5, 83.5) - rest;
  EXPECT_LT(late, 0.9 * early);
  EXPECT_GT(recovered, 0.95 * early);
  EXPECT_GT(recovered, 1.1 * late);
}

double TwitchPeak(const std::vector<SensorFrame>& f, double t0, double rest) {
  double peak = -1e9;
  for (const auto& s : f) {
    if (s.t_s >= t0 && s.t_s < t0 + 0.5) peak = std::max(peak, s.torque_nm - rest);
  }
  return peak;
}

double PotentiationRatio(const Fidelity& fid) {
  const VirtualSubject subject = ExampleSubject(fid);
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(subject, Options(90.0, MotorMode::kLocked)).value();
  SimulatedBench& bench = *bench_owner;
  // Twitch, then the 3 s conditioning burst at 75 % of range (§5.3), twitch.
  model::SampledSignal env = Burst(1.0, 0.0, 1.0, 0.0);
  env.values[200] = 45.0;
  const model::SampledSignal cond = Burst(0.0, 3.0, 1.0, 20.0 + 0.75 * 25.0);
  env.values.insert(env.values.end(), cond.values.begin(), cond.values.end());
  const model::SampledSignal tail = Burst(1.0, 0.0, 1.0, 0.0);
  env.values.insert(env.values.end(), tail.values.begin(), tail.values.end());
  env.values[static_cast<std::size_t>(7.0 * 200)] = 45.0;
  const std::vector<SensorFrame> f = Drive(bench, env);
  const double rest = MeanTorque(f, 0.5, 1.0);
  return TwitchPeak(f, 7.0, rest) / TwitchPeak(f, 1.0, rest);
}

TEST(SimulatedBench, PotentiationRaisesTwitchesAfterConditioning) {
  EXPECT_GT(PotentiationRatio(Fidelity::Default()), 1.08);
  Fidelity no_potentiation = Fidelity::Default();
  no_potentiation.potentiation_max = 0.0;
  EXPECT_LT(PotentiationRatio(no_potentiation), 1.0);  // fatigue alone lowers it
}

double TwitchPeakTime(double kse_nm_per_deg) {
  Fidelity fid = Fidelity::Off();
  fid.series_stiffness_nm_per_deg = kse_nm_per_deg;
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(ExampleSubject(fid), Options(90.0, MotorMode::kLocked)).value();
  SimulatedBench& bench = *bench_owner;
  bench.TriggerPulse(45.0);
  double best_t = 0.0, best = -1e9;
  for (int k = 1; k <= 3000; ++k) {
    bench.AdvanceTo(k * 1e-4);
    const LegTruth s = bench.Truth();
    if (s.brace_torque_nm > best) {
      best = s.brace_torque_nm;
      best_t = s.t_s;
    }
  }
  return best_t;
}

TEST(SimulatedBench, TwitchPeaksLaterWithCompliantSeriesElasticity) {
  const double rigid = TwitchPeakTime(0.0);
  EXPECT_NEAR(rigid, 2.0 / 25.0, 2e-4);  // (n − 1)/a, Eq. 4.4
  const double stiff = TwitchPeakTime(1000.0);
  const double compliant = TwitchPeakTime(4.0);
  EXPECT_NEAR(stiff, rigid, 1e-3);
  EXPECT_GT(compliant, rigid + 2e-3);
}

// --- passive free swing, stops, servo --------------------------------------------

TEST(SimulatedBench, FreeSwingSettlesAtPassiveRestAngle) {
  VirtualSubject subject = DrawVirtualSubject(3);
  subject.fidelity = Fidelity::Off();
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(subject, Options(40.0, MotorMode::kDecoupled)).value();
  SimulatedBench& bench = *bench_owner;
  bench.AdvanceTo(1.0);
  EXPECT_GT(bench.Truth().angle_deg, 45.0);  // it swings
  bench.AdvanceTo(40.0);
  const double rest = model::PassiveRestAngle(subject.truth.passive);
  EXPECT_NEAR(bench.Truth().angle_deg, rest, 0.1);
  EXPECT_NEAR(bench.ReadSensors().angle_deg, rest, 0.1);
}

TEST(SimulatedBench, HardStopsHoldUnderMaximumStimulation) {
  VirtualSubject subject = ExampleSubject(Fidelity::Default());
  subject.truth.active.torque_scale_nm = 60.0;
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(subject, Options(80.0, MotorMode::kDecoupled)).value();
  SimulatedBench& bench = *bench_owner;
  bench.SetStimAmplitude(100.0);
  double min_angle = 1e9, min_late = 1e9;
  bool switch_seen = false;
  for (int k = 1; k <= 3000; ++k) {
    bench.AdvanceTo(k * 1e-3);
    const double th = bench.Truth().angle_deg;
    min_angle = std::min(min_angle, th);
    if (k > 2500) min_late = std::min(min_late, th);
    switch_seen = switch_seen || bench.ReadSensors().limit_extension;
  }
  // The leg strikes the stop at ≈ 600 deg/s: a brief compression of the
  // stop of a few tenths of a degree, then it is held at 10° under maximum
  // stimulation (τ/k_stop < 0.01°).
  EXPECT_GE(min_angle, 9.75);
  EXPECT_LT(min_late, 10.05);
  EXPECT_GE(min_late, 9.99);
  EXPECT_TRUE(switch_seen);

  // Driven into flexion by the servo: the limit switch and the stop hold.
  const std::unique_ptr<SimulatedBench> flex_owner =
      SimulatedBench::Create(ExampleSubject(Fidelity::Default()),
                             Options(90.0, MotorMode::kPosition))
          .value();
  SimulatedBench& flex = *flex_owner;
  flex.SetMotorSetpoint(130.0);
  double max_angle = -1e9;
  for (int k = 1; k <= 2000; ++k) {
    flex.AdvanceTo(k * 1e-3);
    max_angle = std::max(max_angle, flex.Truth().angle_deg);
  }
  EXPECT_GT(max_angle, 107.0);
  EXPECT_LE(max_angle, 110.25);  // coasting into the stop past the limit switch
}

TEST(SimulatedBench, ServoTorqueNeverExceedsLimitAndTracks) {
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(ExampleSubject(Fidelity::Default()),
                             Options(60.0, MotorMode::kPosition))
          .value();
  SimulatedBench& bench = *bench_owner;
  double max_abs = 0.0;
  for (int k = 1; k <= 4000; ++k) {
    bench.SetMotorSetpoint((k / 500) % 2 == 0 ? 30.0 : 100.0);  // square wave, 1 Hz
    bench.AdvanceTo(k * 1e-3);
    max_abs = std::max(max_abs, std::abs(bench.Truth().motor_torque_nm));
  }
  EXPECT_LE(max_abs, 50.0);
  EXPECT_GT(max_abs, 49.9);  // the limit was reached
  // A slow sine is followed within a degree.
  double max_err = 0.0;
  for (int k = 1; k <= 4000; ++k) {
    const double t = 4.0 + k * 1e-3;
    bench.SetMotorSetpoint(60.0 + 30.0 * std::sin(2.0 * model::kPi * 0.25 * t));
    bench.AdvanceTo(t);
    if (k > 1000) {
      max_err = std::max(max_err, std::abs(bench.Truth().angle_deg -
                                           (60.0 + 30.0 * std::sin(2.0 * model::kPi * 0.25 * t))));
    }
  }
  EXPECT_LT(max_err, 1.0);
}

// --- sensors ----------------------------------------------------------------------

TEST(SimulatedBench, TorqueChannelSaturatesAndIsQuantised) {
  VirtualSubject strong = ExampleSubject(Fidelity::Default());
  strong.truth.active.torque_scale_nm = 150.0;
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(strong, Options(90.0, MotorMode::kLocked)).value();
  SimulatedBench& bench = *bench_owner;
  bench.SetStimAmplitude(45.0);
  bench.AdvanceTo(1.5);
  EXPECT_GT(bench.Truth().brace_torque_nm, 100.0);
  EXPECT_DOUBLE_EQ(bench.ReadSensors().torque_nm, 2047 * kLsb);

  VirtualSubject pulled = ExampleSubject(Fidelity::Default());
  pulled.truth.passive.torque_angle = model::PiecewiseLinear::Constant(-100.0);
  const std::unique_ptr<SimulatedBench> neg_owner =
      SimulatedBench::Create(pulled, Options(90.0, MotorMode::kLocked)).value();
  SimulatedBench& neg = *neg_owner;
  neg.AdvanceTo(0.1);
  EXPECT_DOUBLE_EQ(neg.ReadSensors().torque_nm, -2048 * kLsb);

  // Every reading is a whole number of LSBs, and noise makes them vary.
  const std::unique_ptr<SimulatedBench> noisy_owner =
      SimulatedBench::Create(ExampleSubject(Fidelity::Default()), Options(90.0, MotorMode::kLocked))
          .value();
  SimulatedBench& noisy = *noisy_owner;
  noisy.SetStimAmplitude(30.0);
  std::vector<double> codes;
  for (int k = 1; k <= 400; ++k) {
    noisy.AdvanceTo(k * 5e-3);
    const double code = noisy.ReadSensors().torque_nm / kLsb;
    EXPECT_NEAR(code, std::round(code), 1e-6);
    codes.push_back(std::round(code));
  }
  std::sort(codes.begin(), codes.end());
  EXPECT_GT(std::unique(codes.begin(), codes.end()) - codes.begin(), 20);
}

TEST(SimulatedBench, AccelerometerSeesGravityAtItsPlacement) {
  VirtualSubject subject = ExampleSubject(Fidelity::Off());
  subject.anthropometrics.thigh_elevation_deg = 9.0;  // shank vertical at 81°
  const std::unique_ptr<SimulatedBench> locked_owner =
      SimulatedBench::Create(subject, Options(51.0, MotorMode::kLocked)).value();
  SimulatedBench& locked = *locked_owner;
  locked.AdvanceTo(0.05);
  EXPECT_NEAR(locked.ReadSensors().accel_m_s2, 9.80665 * std::sin(-30.0 * model::kPi / 180.0),
              1e-9);
  // Free swing: a = d·θ̈ + g·sin(θ − 81°).
  const std::unique_ptr<SimulatedBench> swing_owner =
      SimulatedBench::Create(subject, Options(40.0, MotorMode::kDecoupled)).value();
  SimulatedBench& swing = *swing_owner;
  swing.AdvanceTo(0.02);
  const LegTruth s = swing.Truth();
  const double expected =
      subject.anthropometrics.accel_distance_m * s.accel_deg_s2 * model::kPi / 180 +
      9.80665 * std::sin((s.angle_deg - 81.0) * model::kPi / 180.0);
  EXPECT_NEAR(swing.ReadSensors().accel_m_s2, expected, 1e-9);
  EXPECT_GT(std::abs(s.accel_deg_s2), 50.0);
}

TEST(SimulatedBench, PotentiometerNonLinearityIsOnePercentOfATurn) {
  Fidelity fid = Fidelity::Off();
  fid.pot_nonlinearity = 0.01;
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(ExampleSubject(fid), Options(60.0, MotorMode::kLocked)).value();
  SimulatedBench& bench = *bench_owner;
  bench.AdvanceTo(0.01);
  // 90° − 30° is a quarter turn from the zero at 90°: full error, −1.2°.
  EXPECT_NEAR(bench.ReadSensors().angle_deg, 60.0 - 1.2, 1e-9);
}

TEST(SimulatedBench, AngleChannelCoversTheRangeInTwelveBits) {
  // One potentiometer turn (120°) over 4096 codes, mid-scale at 60°: every
  // angle of the bench's 10–110° range reads within half an LSB.
  Fidelity fid = Fidelity::Off();
  fid.quantise_adc = true;
  for (double angle : {10.0, 33.3, 60.0, 90.0, 110.0}) {
    const std::unique_ptr<SimulatedBench> bench_owner =
        SimulatedBench::Create(ExampleSubject(fid), Options(angle, MotorMode::kLocked)).value();
    SimulatedBench& bench = *bench_owner;
    bench.AdvanceTo(0.01);
    EXPECT_NEAR(bench.ReadSensors().angle_deg, angle, 120.0 / 4096 / 2 + 1e-9) << angle;
  }
}

TEST(SimulatedBench, LockEngagesDespiteServoDroopUnderGravity) {
  // Start the servo off its set-point: it must carry the leg there and the
  // lock must then hold it rigidly (θ̈ = 0), however strong the muscle.
  SimulatedBenchOptions o = Options(90.0, MotorMode::kLocked);
  o.initial_angle_deg = 70.0;
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(ExampleSubject(Fidelity::Off()), o).value();
  SimulatedBench& bench = *bench_owner;
  bench.AdvanceTo(1.0);
  ASSERT_TRUE(bench.Truth().lock_engaged);
  const double held = bench.Truth().angle_deg;
  EXPECT_NEAR(held, 90.0, 0.5);
  bench.SetStimAmplitude(45.0);  // 40 N·m of quadriceps torque against the lock
  bench.AdvanceTo(3.0);
  EXPECT_EQ(bench.Truth().angle_deg, held);
  EXPECT_GT(bench.ReadSensors().torque_nm, 30.0);
}

TEST(SimulatedBench, EmgHasOneSamplePerMillisecondAndVoluntaryBursts) {
  Fidelity fid = Fidelity::Default();
  fid.cocontraction_per_min = 30.0;
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(ExampleSubject(fid), Options(90.0, MotorMode::kLocked)).value();
  SimulatedBench& bench = *bench_owner;
  bench.AdvanceTo(20.0);
  const std::vector<double> emg = bench.DrainEmg_mv();
  ASSERT_EQ(emg.size(), 20000u);
  // RMS per 250 ms window: bursts stand far above the 5 µV noise floor.
  double lo = 1e9, hi = 0.0;
  for (std::size_t w = 0; w + 250 <= emg.size(); w += 250) {
    double ss = 0.0;
    for (std::size_t i = w; i < w + 250; ++i) ss += emg[i] * emg[i];
    const double rms = std::sqrt(ss / 250);
    lo = std::min(lo, rms);
    hi = std::max(hi, rms);
  }
  EXPECT_LT(lo, 0.01);
  EXPECT_GT(hi, 0.05);
  EXPECT_TRUE(bench.DrainEmg_mv().empty());
}

// --- determinism, e-stop, time ------------------------------------------------------

std::vector<double> Stream(std::uint64_t seed) {
  VirtualSubject subject = DrawVirtualSubject(11);
  subject.fidelity.cocontraction_per_min = 10.0;
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(subject, Options(80.0, MotorMode::kDecoupled, seed)).value();
  SimulatedBench& bench = *bench_owner;
  std::vector<double> out;
  for (int i = 0; i < 1000; ++i) {
    bench.SetStimAmplitude((i / 40) % 3 == 1 ? 45.0 : 0.0);
    const SensorFrame f = bench.ReadSensors();
    out.insert(out.end(), {f.angle_deg, f.torque_nm, f.accel_m_s2, f.stim_ma});
    bench.AdvanceTo((i + 1) / 200.0);
  }
  const std::vector<double> emg = bench.DrainEmg_mv();
  out.insert(out.end(), emg.begin(), emg.end());
  return out;
}

TEST(SimulatedBench, DeterministicForASeedAndDifferentForAnother) {
  const std::vector<double> a = Stream(7), b = Stream(7), c = Stream(8);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_TRUE(a == b);  // bit-identical
  ASSERT_EQ(a.size(), c.size());
  std::size_t differ = 0;
  for (std::size_t i = 0; i < a.size(); ++i) differ += a[i] != c[i];
  EXPECT_GT(differ, a.size() / 2);
}

TEST(SimulatedBench, EStopFromAnotherThreadZeroesStimulationWithinOneControlPeriod) {
  SimulatedBenchOptions o = Options(90.0, MotorMode::kLocked);
  SimulatedBench* self = nullptr;
  double estop_at = -1.0;
  o.on_control_step = [&](double t) {
    if (estop_at < 0.0 && t >= 0.5) {
      std::thread other([&] { self->HardwareEStop(); });
      other.join();
      estop_at = t;
    }
  };
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(ExampleSubject(Fidelity::Off()), o).value();
  SimulatedBench& bench = *bench_owner;
  self = &bench;
  bench.SetStimAmplitude(40.0);
  bench.AdvanceTo(1.0);
  ASSERT_NEAR(estop_at, 0.5, 1e-9);
  const model::PulseTrain pulses = bench.DeliveredPulses();
  ASSERT_FALSE(pulses.empty());
  EXPECT_LT(pulses.back().t_s, estop_at + 1e-9);
  EXPECT_GT(pulses.back().t_s, estop_at - 1.0 / 33.0 - 1e-9);  // the train ran until then
  const SensorFrame f = bench.ReadSensors();
  EXPECT_TRUE(f.estop);
  EXPECT_EQ(f.stim_ma, 0.0);
  EXPECT_FALSE(bench.Truth().lock_engaged);  // motor power cut
  // Commands while latched deliver nothing; clearing and re-commanding works.
  bench.TriggerPulse(40.0);
  bench.SetStimAmplitude(40.0);
  bench.AdvanceTo(1.2);
  EXPECT_EQ(bench.DeliveredPulses().size(), pulses.size());
  bench.ClearHardwareEStop();
  bench.SetStimAmplitude(0.0);
  bench.SetStimAmplitude(40.0);
  // The pulse clock runs on (docs/MODEL.md): the next pulse at the next grid
  // time, 40/33 s, not at the command.
  EXPECT_EQ(bench.DeliveredPulses().size(), pulses.size());
  bench.AdvanceTo(1.22);
  ASSERT_EQ(bench.DeliveredPulses().size(), pulses.size() + 1);
  EXPECT_NEAR(bench.DeliveredPulses().back().t_s, 40.0 / 33.0, 1e-9);
}

TEST(SimulatedBench, TimeScalePacesAgainstTheInjectedClock) {
  // Sleeping advances the clock and is counted.
  struct CountingClock : ::fesbench::testing::ManualClock {
    using ManualClock::ManualClock;
    void SleepFor(double s) override {
      ManualClock::SleepFor(s);
      ++sleeps;
    }
    int sleeps = 0;
  } clock(100.0);
  int& sleeps = clock.sleeps;
  SimulatedBenchOptions o = Options(90.0, MotorMode::kLocked);
  o.clock = &clock;
  o.time_scale = 2.0;
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(ExampleSubject(Fidelity::Off()), o).value();
  SimulatedBench& bench = *bench_owner;
  bench.AdvanceTo(1.0);
  EXPECT_NEAR(clock.MonotonicSeconds() - 100.0, (1.0 - 1e-3) / 2.0,
              1e-9);  // anchored at the first step
  EXPECT_GT(sleeps, 900);
  bench.set_time_scale(0.0);
  const int before = sleeps;
  bench.AdvanceTo(2.0);
  EXPECT_EQ(sleeps, before);
  EXPECT_DOUBLE_EQ(bench.Now_s(), 2.0);
}

TEST(SimulatedBench, RejectsAnInvalidSubject) {
  VirtualSubject s = ExampleSubject(Fidelity::Default());
  s.max_tolerated_ma = 10.0;
  const auto r = SimulatedBench::Create(s);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().field(), "max_tolerated_ma");
}

}  // namespace
}  // namespace fesbench::server
