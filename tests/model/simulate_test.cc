#include "model/simulate.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "model/joint_model.h"
#include "model/units.h"

namespace fesbench::model {
namespace {

// A seeded random-binary envelope: 0.25 s slots, each on (stim_ma) or off.
PulseTrain RandomBinaryPulses(double duration_s, double stim_ma, unsigned seed) {
  std::mt19937 rng(seed);
  std::bernoulli_distribution on(0.5);
  SampledSignal env;
  env.rate_hz = 200.0;
  const int slot = 50;  // samples per 0.25 s slot
  const int n = static_cast<int>(duration_s * env.rate_hz);
  for (int i = 0; i < n; i += slot) {
    const double v = on(rng) ? stim_ma : 0.0;
    for (int k = 0; k < slot && i + k < n; ++k) env.values.push_back(v);
  }
  return PulsesFromEnvelope(env, 33.0);
}

// Linear passive system: τ_pta = k·(θ − 90°), τ_ptv = c·θ̇, no active torque.
ParameterSet LinearPassive(double k_nm_per_deg, double c_nm_s_per_deg) {
  ParameterSet p = ExampleParameterSet();
  p.passive.inertia_kgm2 = 0.36;
  p.passive.torque_angle =
      PiecewiseLinear({-1000.0, 1000.0}, {k_nm_per_deg * -1090.0, k_nm_per_deg * 910.0});
  p.passive.torque_velocity =
      PiecewiseLinear({-1e4, 1e4}, {-c_nm_s_per_deg * 1e4, c_nm_s_per_deg * 1e4});
  p.active.torque_scale_nm = 0.0;
  return p;
}

TEST(SimulateTest, LinearPassiveFreeResponseMatchesClosedForm) {
  const double k = 0.5, c = 0.01, j = 0.36;
  const ParameterSet p = LinearPassive(k, c);
  // In radians: J·θ̈ = −K·(θ − θ_eq) − C·θ̇ with K = k·180/π, C = c·180/π.
  const double kk = k * kDegPerRad, cc = c * kDegPerRad;
  const double wn = std::sqrt(kk / j), zeta = cc / (2.0 * std::sqrt(kk * j));
  const double wd = wn * std::sqrt(1.0 - zeta * zeta);
  const double x0 = DegToRad(20.0), v0 = DegToRad(-30.0);
  for (IntegratorKind kind : {IntegratorKind::kRk4, IntegratorKind::kAdaptive}) {
    SimulationOptions o;
    o.integrator = kind;
    o.duration_s = 5.0;
    o.initial_angle_deg = 110.0;
    o.initial_velocity_deg_s = -30.0;
    o.tolerances = {1e-11, 1e-11, 1e-12, 0.01, 10'000'000};
    const SimulationResult r = SimulateFreeSwing(p, {}, o);
    ASSERT_EQ(r.size(), 1000u);
    double max_err = 0.0;
    for (std::size_t i = 0; i < r.size(); ++i) {
      const double t = r.t_s[i];
      const double x = std::exp(-zeta * wn * t) *
                       (x0 * std::cos(wd * t) + (v0 + zeta * wn * x0) / wd * std::sin(wd * t));
      max_err = std::max(max_err, std::abs(DegToRad(r.angle_deg[i] - 90.0) - x));
    }
    EXPECT_LT(max_err, 1e-6) << IntegratorKindName(kind);
    EXPECT_EQ(r.torque_nm[100], 0.0);
  }
}

// A constant passive torque falls the knee at constant angular acceleration
// onto the extension stop, where it stays: θ = θ₀ − ½·a·t² until
// t* = √(2(θ₀ − θ_min)/a), then θ = θ_min, θ̇ = θ̈ = 0.
TEST(SimulateTest, JointLimitsStopTheKneeDead) {
  ParameterSet p = LinearPassive(0.0, 0.0);
  const double tau = 2.0, j = p.passive.inertia_kgm2;
  p.passive.torque_angle = PiecewiseLinear::Constant(tau, 90.0);
  const double a = RadToDeg(tau / j);  // deg/s², towards extension
  const double theta0 = 50.0;
  const double t_stop = std::sqrt(2.0 * (theta0 - 10.0) / a);
  for (IntegratorKind kind : {IntegratorKind::kRk4, IntegratorKind::kAdaptive}) {
    SimulationOptions o;
    o.integrator = kind;
    o.duration_s = 2.0;
    o.initial_angle_deg = theta0;
    o.joint_limits = JointLimits{10.0, 110.0};
    const SimulationResult r = SimulateFreeSwing(p, {}, o);
    for (std::size_t i = 0; i < r.size(); ++i) {
      const double t = r.t_s[i];
      if (t < t_stop - 2e-3) {
        EXPECT_NEAR(r.angle_deg[i], theta0 - 0.5 * a * t * t, 1e-6) << t;
        EXPECT_NEAR(r.velocity_deg_s[i], -a * t, 1e-6) << t;
      } else if (t > t_stop + 2e-3) {
        EXPECT_EQ(r.angle_deg[i], 10.0) << t;
        EXPECT_EQ(r.velocity_deg_s[i], 0.0) << t;
        EXPECT_EQ(r.accel_deg_s2[i], 0.0) << t;
      }
      EXPECT_GE(r.angle_deg[i], 10.0);
    }
    // Without limits the same knee falls through the stop.
    o.joint_limits.reset();
    EXPECT_LT(SimulateFreeSwing(p, {}, o).angle_deg.back(), 0.0) << IntegratorKindName(kind);
  }
  // The flexion stop: the torque reversed.
  p.passive.torque_angle = PiecewiseLinear::Constant(-tau, 90.0);
  SimulationOptions o;
  o.duration_s = 2.0;
  o.initial_angle_deg = 100.0;
  o.joint_limits = JointLimits{10.0, 110.0};
  const SimulationResult r = SimulateFreeSwing(p, {}, o);
  EXPECT_EQ(r.angle_deg.back(), 110.0);
  EXPECT_EQ(r.velocity_deg_s.back(), 0.0);
  EXPECT_LE(*std::max_element(r.angle_deg.begin(), r.angle_deg.end()), 110.0);
}

TEST(SimulateTest, Rk4AndAdaptiveAgreeOnRandomBinaryFreeSwing) {
  const ParameterSet p = ExampleParameterSet();
  const PulseTrain pulses = RandomBinaryPulses(10.0, 40.0, 20261121u);
  ASSERT_GT(pulses.size(), 50u);
  SimulationOptions o;
  o.duration_s = 10.0;
  const SimulationResult rk4 = SimulateFreeSwing(p, pulses, o);
  o.integrator = IntegratorKind::kAdaptive;
  o.tolerances = {1e-9, 1e-9, 1e-12, 0.01, 10'000'000};
  const SimulationResult dp = SimulateFreeSwing(p, pulses, o);
  ASSERT_EQ(rk4.size(), 2000u);
  ASSERT_EQ(dp.size(), rk4.size());
  double max_diff = 0.0, range_lo = 1e9, range_hi = -1e9;
  for (std::size_t i = 0; i < rk4.size(); ++i) {
    max_diff = std::max(max_diff, std::abs(rk4.angle_deg[i] - dp.angle_deg[i]));
    range_lo = std::min(range_lo, rk4.angle_deg[i]);
    range_hi = std::max(range_hi, rk4.angle_deg[i]);
  }
  EXPECT_LT(max_diff, 0.01);
  EXPECT_GT(range_hi - range_lo, 20.0);        // the test exercises real motion
  EXPECT_GE(rk4.stats.accepted_steps, 10000);  // 1 kHz plus pulse splits
}

// SimulateFreeSwing's RK4 (JointModel::FreeSwingRk4Step, the stages
// arranged for their dependency chain) against Rk4Stages over
// AccelerationDegS2 through the same RunPulseDriven: the same discrete map
// up to rounding, over a swing that crosses every table's segments.
TEST(SimulateTest, ArrangedRk4StepIsRk4Stages) {
  ParameterSet p = ExampleParameterSet();
  const PulseTrain pulses = RandomBinaryPulses(10.0, 40.0, 20261128u);
  SimulationOptions o;
  o.duration_s = 10.0;
  o.output_rate_hz = 1000.0;
  const SimulationResult fast = SimulateFreeSwing(p, pulses, o);

  using Xy = Eigen::Vector2d;  // (θ, θ̇)
  const JointModel model = JointModel::FromParameters(p);
  ASSERT_TRUE(model.has_scaled_tables());
  const auto rhs = [&model](double /*t*/, const Xy& x, double a) {
    return Xy(x[1], model.AccelerationDegS2(x[0], x[1], a));
  };
  std::vector<double> angle(fast.size()), velocity(fast.size());
  const auto record = [&](std::size_t i, double /*t*/, const Xy& x, double /*a*/) {
    angle[i] = x[0];
    velocity[i] = x[1];
  };
  IntegratorWorkspace ws;
  detail::RunPulseDriven(rhs, record, Xy(o.initial_angle_deg, o.initial_velocity_deg_s),
                         p.contraction, p.irc, pulses, o.pulse_rate_hz, o.output_rate_hz,
                         fast.size(), {IntegratorKind::kRk4, o.step_s, o.tolerances}, ws);
  double max_angle = 0.0, max_velocity = 0.0, lo = 1e9, hi = -1e9, v_lo = 1e9, v_hi = -1e9;
  for (std::size_t i = 0; i < fast.size(); ++i) {
    max_angle = std::max(max_angle, std::abs(fast.angle_deg[i] - angle[i]));
    max_velocity = std::max(max_velocity, std::abs(fast.velocity_deg_s[i] - velocity[i]));
    lo = std::min(lo, angle[i]);
    hi = std::max(hi, angle[i]);
    v_lo = std::min(v_lo, velocity[i]);
    v_hi = std::max(v_hi, velocity[i]);
  }
  EXPECT_LT(max_angle, 1e-9);
  EXPECT_LT(max_velocity, 1e-8);
  // The swing crosses the angle tables' 10°-spaced breakpoints and the
  // velocity tables' ±50…±400 deg/s ones.
  EXPECT_GT(hi - lo, 100.0);
  EXPECT_LT(v_lo, -400.0);
  EXPECT_GT(v_hi, 400.0);
}

TEST(SimulateTest, FreeSwingColumnsSatisfyTheEquationOfMotion) {
  const ParameterSet p = ExampleParameterSet();
  const PulseTrain pulses = RandomBinaryPulses(3.0, 38.0, 7u);
  SimulationOptions o;
  o.duration_s = 3.0;
  const SimulationResult r = SimulateFreeSwing(p, pulses, o);
  const auto act = ActivationAt(p.contraction, p.irc, pulses, 33.0, r.t_s);
  for (std::size_t i = 0; i < r.size(); ++i) {
    const double th = r.angle_deg[i], v = r.velocity_deg_s[i];
    EXPECT_NEAR(r.activation[i], act[i], 1e-12);
    // J·θ̈ + τ_pta + τ_ptv + τ_act = τ_motor = 0.
    const double tau_act =
        act[i] * p.active.torque_scale_nm * p.active.torque_angle(th) * p.active.torque_velocity(v);
    EXPECT_NEAR(0.36 * DegToRad(r.accel_deg_s2[i]) + p.passive.torque_angle(th) +
                    p.passive.torque_velocity(v) + tau_act,
                0.0, 1e-9);
  }
}

TEST(SimulateTest, StimulationExtendsTheKnee) {
  const ParameterSet p = ExampleParameterSet();
  PulseTrain pulses;
  for (int k = 0; k < 10; ++k) pulses.push_back({0.5 + k / 33.0, 40.0});
  SimulationOptions o;
  o.duration_s = 1.0;
  o.initial_angle_deg = 81.0;
  const SimulationResult rest = SimulateFreeSwing(p, {}, o);
  const SimulationResult stim = SimulateFreeSwing(p, pulses, o);
  EXPECT_EQ(rest.angle_deg[99], stim.angle_deg[99]);  // t < first pulse: identical
  EXPECT_LT(stim.angle_deg[160], rest.angle_deg[160] - 5.0);
}

TEST(SimulateTest, PulsesActAtTheirExactTimes) {
  // A single pulse off the 1 ms grid gives the closed-form twitch exactly.
  ParameterSet p = ExampleParameterSet();
  SimulationOptions o;
  o.duration_s = 0.5;
  o.output_rate_hz = 1000.0;
  const double tp = 0.10037;
  const SimulationResult r = SimulateFreeSwing(p, {{tp, 45.0}}, o);
  for (std::size_t i = 0; i < r.size(); ++i) {
    EXPECT_NEAR(r.activation[i], ImpulseResponse(p.contraction, r.t_s[i] - tp) * 1.0 / 33.0, 1e-12);
  }
}

TEST(SimulateTest, IsometricTorqueIsPassivePlusActive) {
  const ParameterSet p = ExampleParameterSet();
  const PulseTrain pulses = RandomBinaryPulses(4.0, 42.0, 3u);
  SimulationOptions o;
  o.duration_s = 4.0;
  for (double th : {30.0, 75.0, 100.0}) {
    const SimulationResult r = SimulateIsometric(p, pulses, th, o);
    const auto act = ActivationAt(p.contraction, p.irc, pulses, 33.0, r.t_s);
    for (std::size_t i = 0; i < r.size(); ++i) {
      // Eqs. 3.18–3.20 with the referenced τ_ptv(0).
      const double expected = p.passive.torque_angle(th) + p.passive.torque_velocity(0.0) +
                              p.active.torque_scale_nm * p.active.torque_angle(th) *
                                  p.active.torque_velocity(0.0) * act[i];
      EXPECT_NEAR(r.torque_nm[i], expected, 1e-12);
      EXPECT_EQ(r.angle_deg[i], th);
      EXPECT_EQ(r.velocity_deg_s[i], 0.0);
    }
  }
}

// θ(t) = 60 + 25·sin(2π·0.7·t) degrees.
class SineTrajectory final : public Trajectory {
 public:
  Kinematics At(double t) const override {
    const double w = 2.0 * kPi * 0.7;
    return {60.0 + 25.0 * std::sin(w * t), 25.0 * w * std::cos(w * t),
            -25.0 * w * w * std::sin(w * t)};
  }
  double duration_s() const override { return 3.0; }
};

TEST(SimulateTest, TrajectoryTorqueFollowsEquation49WithActiveTerm) {
  const ParameterSet p = ExampleParameterSet();
  const PulseTrain pulses = RandomBinaryPulses(3.0, 36.0, 11u);
  const SineTrajectory traj;
  const SimulationResult r = SimulateTrajectory(p, pulses, traj, {});
  ASSERT_EQ(r.size(), 600u);  // duration from the trajectory
  const auto act = ActivationAt(p.contraction, p.irc, pulses, 33.0, r.t_s);
  for (std::size_t i = 0; i < r.size(); ++i) {
    const Kinematics k = traj.At(r.t_s[i]);
    const double expected = 0.36 * DegToRad(k.accel_deg_s2) +
                            p.passive.torque_velocity(k.velocity_deg_s) +
                            p.passive.torque_angle(k.angle_deg) +
                            act[i] * 40.0 * p.active.torque_angle(k.angle_deg) *
                                p.active.torque_velocity(k.velocity_deg_s);
    EXPECT_NEAR(r.torque_nm[i], expected, 1e-10);
    EXPECT_EQ(r.angle_deg[i], k.angle_deg);
  }
}

TEST(SimulateTest, VariantEquivalencesHoldInSimulation) {
  ParameterSet p = ExampleParameterSet();
  p.active.torque_angle = PiecewiseLinear::Constant(1.0, 90.0);
  p.active.torque_velocity = PiecewiseLinear::Constant(1.0, 0.0);
  p.single_segment = {0.0, 1.0, 0.0, 1.0};
  const PulseTrain pulses = RandomBinaryPulses(3.0, 40.0, 5u);
  SimulationOptions o;
  o.duration_s = 3.0;
  const SimulationResult full = SimulateFreeSwing(p, pulses, o);
  o.model_kind = ModelKind::kTorqueGenerator;
  const SimulationResult tg = SimulateFreeSwing(p, pulses, o);
  o.model_kind = ModelKind::kSingleSegment;
  const SimulationResult ss = SimulateFreeSwing(p, pulses, o);
  EXPECT_EQ(tg.model, ModelKind::kTorqueGenerator);
  EXPECT_EQ(full.angle_deg, tg.angle_deg);
  EXPECT_EQ(ss.angle_deg, tg.angle_deg);
  EXPECT_EQ(ss.velocity_deg_s, tg.velocity_deg_s);
}

TEST(SimulateTest, StimulusColumnRule) {
  const PulseTrain pulses = {{0.1, 30.0}, {0.1 + 1 / 33.0, 35.0}, {0.5, 40.0}};
  const std::vector<double> t = {0.0, 0.1, 0.12, 0.135, 0.16, 0.3, 0.5, 0.52, 0.54};
  const auto s = StimulusColumn(pulses, 33.0, t);
  // Sample i covers [t_i, t_{i+1}): the pulse inside it, else the previous
  // pulse while its train goes on (the next one period later), else 0.
  const std::vector<double> expected = {0, 30, 35, 0, 0, 0, 40, 0, 0};
  EXPECT_EQ(s, expected);
  // A train holds its amplitude between pulses.
  PulseTrain train;
  for (int k = 10; k < 20; ++k) train.push_back({k / 33.0, 25.0});
  const std::vector<double> t2 = {0.30, 0.31, 0.32, 0.33, 0.5, 0.57, 0.58, 0.59};
  const std::vector<double> expected2 = {25, 25, 25, 25, 25, 25, 0, 0};  // last pulse 19/33 ≈ 0.576
  EXPECT_EQ(StimulusColumn(train, 33.0, t2), expected2);
}

// The simulator's stim_ma column read as an envelope gives the pulses back:
// isolated impulses are not doubled, trains stay on their grid.
TEST(SimulateTest, StimulusColumnRoundTripsThroughPulsesFromEnvelope) {
  SampledSignal env{200.0, 0.0, std::vector<double>(2400, 0.0)};
  env.values[50] = 40.0;                                            // impulse off the grid (0.25 s)
  env.values[800] = 45.0;                                           // impulse on the grid (4 s)
  for (int i = 230; i < 530; ++i) env.values[i] = 20.0 + 0.05 * i;  // a ramp burst
  for (int i = 1203; i < 1260; ++i) env.values[i] = 30.0;
  env.values[1500] = 33.0;  // impulse (7.5 s)
  const PulseTrain pulses = PulsesFromEnvelope(env, 33.0);
  SimulationOptions o;
  o.duration_s = env.EndTime();
  const SimulationResult r = SimulateIsometric(ExampleParameterSet(), pulses, 90.0, o);
  const PulseTrain again = PulsesFromEnvelope(SampledSignal{200.0, 0.0, r.stim_ma}, 33.0);
  ASSERT_EQ(again.size(), pulses.size());
  for (std::size_t i = 0; i < pulses.size(); ++i) {
    EXPECT_NEAR(again[i].t_s, pulses[i].t_s, 1e-12) << i;
    EXPECT_EQ(again[i].stim_ma, pulses[i].stim_ma) << i;
  }
  // Each impulse is one sample of the column.
  for (double t : {0.25, 4.0, 7.5}) {
    const auto i = static_cast<std::size_t>(std::llround(t * 200.0));
    EXPECT_GT(r.stim_ma[i], 0.0);
    EXPECT_EQ(r.stim_ma[i + 1], 0.0) << t;
  }
}

TEST(SimulateTest, OutputGridAndDefaults) {
  const ParameterSet p = ExampleParameterSet();
  SimulationOptions o;
  const SimulationResult r = SimulateFreeSwing(p, {{0.2, 30.0}}, o);
  ASSERT_EQ(r.size(), 240u);  // last pulse + 1 s at 200 Hz
  EXPECT_DOUBLE_EQ(r.t_s[1], 0.005);
  for (const auto* col : {&r.stim_ma, &r.angle_deg, &r.velocity_deg_s, &r.accel_deg_s2,
                          &r.torque_nm, &r.activation}) {
    EXPECT_EQ(col->size(), r.size());
  }
}

TEST(SimulateTest, RejectsBadInput) {
  const ParameterSet p = ExampleParameterSet();
  SimulationOptions o;
  o.duration_s = 1.0;
  EXPECT_THROW(SimulateFreeSwing(p, {{NAN, 30.0}}, o), std::invalid_argument);
  EXPECT_THROW(SimulateFreeSwing(p, {{0.2, INFINITY}}, o), std::invalid_argument);
  EXPECT_THROW(SimulateFreeSwing(p, {{0.2, 30.0}, {0.2, 30.0}}, o), std::invalid_argument);
  EXPECT_THROW(SimulateFreeSwing(p, {{0.3, 30.0}, {0.2, 30.0}}, o), std::invalid_argument);
  SimulationOptions bad = o;
  bad.duration_s = 0.0;
  EXPECT_THROW(SimulateFreeSwing(p, {}, bad), std::invalid_argument);
  bad = o;
  bad.initial_angle_deg = 181.0;
  EXPECT_THROW(SimulateFreeSwing(p, {}, bad), std::invalid_argument);
  bad = o;
  bad.initial_velocity_deg_s = NAN;
  EXPECT_THROW(SimulateFreeSwing(p, {}, bad), std::invalid_argument);
  bad = o;
  bad.joint_limits = JointLimits{50.0, 40.0};
  EXPECT_THROW(SimulateFreeSwing(p, {}, bad), std::invalid_argument);
  bad.joint_limits = JointLimits{10.0, 80.0};  // θ₀ = 90° outside
  EXPECT_THROW(SimulateFreeSwing(p, {}, bad), std::invalid_argument);
  bad.joint_limits = JointLimits{NAN, 110.0};
  EXPECT_THROW(SimulateFreeSwing(p, {}, bad), std::invalid_argument);
  bad = o;
  bad.step_s = -1e-3;
  EXPECT_THROW(SimulateFreeSwing(p, {}, bad), std::invalid_argument);
  bad = o;
  bad.output_rate_hz = NAN;
  EXPECT_THROW(SimulateIsometric(p, {}, 90.0, bad), std::invalid_argument);
  bad = o;
  bad.pulse_rate_hz = 0.0;
  EXPECT_THROW(SimulateIsometric(p, {}, 90.0, bad), std::invalid_argument);
  EXPECT_THROW(SimulateIsometric(p, {}, -31.0, o), std::invalid_argument);
  EXPECT_THROW(SimulateIsometric(p, {}, NAN, o), std::invalid_argument);
  ParameterSet bad_p = p;
  bad_p.contraction.order = 1;
  EXPECT_THROW(SimulateIsometric(bad_p, {}, 90.0, o), std::invalid_argument);
  try {
    bad = o;
    bad.duration_s = -1.0;
    SimulateFreeSwing(p, {}, bad);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("duration_s"), std::string::npos);
  }
}

}  // namespace
}  // namespace fesbench::model
