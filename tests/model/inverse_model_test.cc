// The model inverted for control (docs/MODEL.md, thesis §7.6.3): targets with
// exact derivatives, the inverse recruitment curve, the static inverse in
// closed form, the inverse of a known leg's forward model reproducing the
// trajectory, and the PID's closed-form behaviour.

#include "model/inverse_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "model/joint_model.h"
#include "model/simulate.h"

namespace fesbench::model {
namespace {

TEST(KneeTargetTest, SineAndHoldsHaveExactDerivatives) {
  const KneeTarget sine = SineTarget(30.0, 80.0, 0.2, 10.0);
  ASSERT_EQ(sine.size(), 2001u);
  EXPECT_DOUBLE_EQ(sine.angle_deg.front(), 55.0);
  EXPECT_NEAR(sine.velocity_deg_s.front(), 25.0 * 2.0 * std::numbers::pi * 0.2, 1e-12);
  // Derivatives agree with central differences of the angle.
  for (std::size_t i = 1; i + 1 < sine.size(); i += 97) {
    EXPECT_NEAR(sine.velocity_deg_s[i], (sine.angle_deg[i + 1] - sine.angle_deg[i - 1]) * 100.0,
                1e-3);
  }
  const KneeTarget holds = HoldsTarget({90.0, 40.0, 70.0}, 2.0, 1.0);
  EXPECT_DOUBLE_EQ(holds.duration_s(), 8.0);
  EXPECT_DOUBLE_EQ(holds.angle_deg[100], 90.0);   // holding
  EXPECT_NEAR(holds.angle_deg[500], 65.0, 1e-9);  // halfway down 90 → 40
  EXPECT_DOUBLE_EQ(holds.angle_deg.back(), 70.0);
  for (std::size_t i = 1; i + 1 < holds.size(); i += 13) {
    EXPECT_NEAR(holds.velocity_deg_s[i], (holds.angle_deg[i + 1] - holds.angle_deg[i - 1]) * 100.0,
                0.05);
  }
  const KneeTarget sampled = SampledTarget(sine.angle_deg, 200.0);
  EXPECT_NEAR(sampled.velocity_deg_s[1000], sine.velocity_deg_s[1000], 1e-3);
  EXPECT_NEAR(sampled.accel_deg_s2[1000], sine.accel_deg_s2[1000], 0.05);
  EXPECT_THROW(SineTarget(80.0, 30.0, 0.2, 10.0), std::invalid_argument);
  EXPECT_THROW(HoldsTarget({}, 1.0, 1.0), std::invalid_argument);
  EXPECT_THROW(SampledTarget({1.0, 2.0}, 200.0), std::invalid_argument);
}

TEST(InverseRecruitmentTest, InvertsTheRisingPart) {
  const PiecewiseLinear irc({0.0, 20.0, 45.0, 60.0}, {0.0, 0.0, 1.0, 1.0});
  for (double u : {20.5, 25.0, 32.5, 44.0}) EXPECT_NEAR(InverseRecruitment(irc, irc(u)), u, 1e-12);
  EXPECT_DOUBLE_EQ(InverseRecruitment(irc, 0.0), 0.0);  // nothing asked: no stimulation
  EXPECT_DOUBLE_EQ(InverseRecruitment(irc, -0.3), 0.0);
  EXPECT_DOUBLE_EQ(InverseRecruitment(irc, 1.0), 45.0);  // the top, where first reached
  EXPECT_DOUBLE_EQ(InverseRecruitment(irc, 1.4), 45.0);
  EXPECT_THROW(InverseRecruitment(PiecewiseLinear(), 0.5), std::invalid_argument);
}

TEST(InverseModelTest, AHoldNeedsTheStaticActivation) {
  const ParameterSet params = ExampleParameterSet();
  const JointModel joint = JointModel::FromParameters(params);
  const double angle = 50.0;
  const Feedforward ff = InvertModel(params, HoldsTarget({angle}, 2.0, 1.0), {});
  // Closed form at rest: f_stim·τ_scale·f_ata(θ)·f_atv(0) = −τ_pta(θ) − τ_ptv(0).
  const double expected = (-joint.PassiveAngleTorque(angle) - joint.PassiveVelocityTorque(0.0)) /
                          joint.ActiveGain(angle, 0.0);
  ASSERT_GT(expected, 0.0);
  ASSERT_LT(expected, 1.0);
  for (double f : ff.activation) EXPECT_NEAR(f, expected, 1e-12);
  EXPECT_NEAR(ff.amplitude_ma.front(), InverseRecruitment(params.irc, expected), 1e-12);
  // One pulse per tick of the 33 Hz clock over the 2 s.
  EXPECT_EQ(ff.pulses.size(), 67u);
  EXPECT_DOUBLE_EQ(ff.pulses[33].t_s, 1.0);
  for (unsigned char s : ff.saturated) EXPECT_EQ(s, 0);
}

TEST(InverseModelTest, TheInverseOfAKnownLegReproducesItsTrajectory) {
  const ParameterSet params = ExampleParameterSet();
  // Start at the sine's first angle and hold 1 s (the contraction chain
  // fills), then a 0.2 Hz sine 40–70° for 10 s: the shape of the tracking target (docs/STUDY.md).
  KneeTarget target = HoldsTarget({55.0}, 1.0, 1.0);
  const KneeTarget sine = SineTarget(40.0, 70.0, 0.2, 10.0);
  for (std::size_t i = 1; i < sine.size(); ++i) {
    target.angle_deg.push_back(sine.angle_deg[i]);
    target.velocity_deg_s.push_back(sine.velocity_deg_s[i]);
    target.accel_deg_s2.push_back(sine.accel_deg_s2[i]);
  }
  SimulationOptions sim;
  sim.duration_s = target.duration_s();
  sim.initial_angle_deg = 55.0;
  auto rms_after_first_second = [&](const Feedforward& ff) {
    // The chain starts empty while the hold needs it full: judge from 1 s on.
    const SimulationResult r = SimulateFreeSwing(params, ff.pulses, sim);
    double sum = 0.0;
    std::size_t count = 0;
    for (std::size_t i = 200; i < target.size() && i < r.angle_deg.size(); ++i) {
      sum += std::pow(r.angle_deg[i] - target.angle_deg[i], 2);
      ++count;
    }
    return std::sqrt(sum / static_cast<double>(count));
  };
  const Feedforward compensated = InvertModel(params, target, {});
  InverseOptions plain;
  plain.compensate_contraction = false;
  const Feedforward uncompensated = InvertModel(params, target, plain);
  const double rms = rms_after_first_second(compensated);
  const double rms_plain = rms_after_first_second(uncompensated);
  std::cout << "[ figure ] open-loop inverse on the example leg, 0.2 Hz sine 40–70°: RMS " << rms
            << " deg (without the contraction lead " << rms_plain << " deg)\n";
  EXPECT_LT(rms, 1.5);
  EXPECT_LT(rms, rms_plain) << "the lead of n/a compensates the contraction dynamics";
  for (unsigned char s : compensated.saturated) EXPECT_EQ(s, 0);
}

TEST(InverseModelTest, UnreachableTargetsAreMarkedAndCapped) {
  const ParameterSet params = ExampleParameterSet();
  InverseOptions options;
  options.max_amplitude_ma = 30.0;
  // Full extension held: more than the muscle (or the cap) gives.
  const Feedforward ff = InvertModel(params, HoldsTarget({5.0}, 1.0, 1.0), options);
  for (std::size_t i = 0; i < ff.amplitude_ma.size(); ++i) {
    EXPECT_LE(ff.amplitude_ma[i], 30.0);
    EXPECT_EQ(ff.saturated[i], 1);
  }
  for (const Pulse& p : ff.pulses) EXPECT_LE(p.stim_ma, 30.0);
}

TEST(PidTest, ClosedFormsOnAFirstOrderPlant) {
  // P only: amplitude = kp·(θ − θ*). Plant: θ settles at θ₀ − g·u (g deg/mA),
  // so the steady error is (θ₀ − θ*)/(1 + kp·g) — the closed form of a
  // proportional loop.
  const double theta0 = 90.0, target = 60.0, g = 1.5;
  Pid p({2.0, 0.0, 0.0, 0.0}, 0.01, 0.0, 1000.0);
  double theta = theta0;
  for (int k = 0; k < 5000; ++k) {
    const double u = p.Update(target, theta);
    theta += 0.01 / 0.2 * ((theta0 - g * u) - theta);  // first-order lag, 0.2 s
  }
  EXPECT_NEAR(theta - target, (theta0 - target) / (1.0 + 2.0 * g), 1e-6);
  // With the integral the error goes to zero.
  Pid pi({2.0, 4.0, 0.0, 0.0}, 0.01, 0.0, 1000.0);
  theta = theta0;
  for (int k = 0; k < 20000; ++k) {
    const double u = pi.Update(target, theta);
    theta += 0.01 / 0.2 * ((theta0 - g * u) - theta);
  }
  EXPECT_NEAR(theta, target, 1e-6);
  // Saturated: the output stays at its limit and the integral stops growing.
  Pid capped({2.0, 4.0, 0.0, 0.0}, 0.01, 0.0, 5.0);
  theta = theta0;
  double integral_at_1s = 0.0;
  for (int k = 0; k < 300; ++k) {
    const double u = capped.Update(target, theta);
    EXPECT_LE(u, 5.0);
    theta += 0.01 / 0.2 * ((theta0 - g * u) - theta);
    if (k == 100) integral_at_1s = capped.integral();
  }
  EXPECT_TRUE(capped.saturated());
  EXPECT_DOUBLE_EQ(capped.integral(), integral_at_1s);
  // The derivative acts on the measurement: a jump of the target alone
  // moves the output only by kp·jump.
  Pid d({1.0, 0.0, 10.0, 0.0}, 0.01, -1000.0, 1000.0);
  EXPECT_DOUBLE_EQ(d.Update(60.0, 60.0), 0.0);
  EXPECT_DOUBLE_EQ(d.Update(50.0, 60.0), 10.0);
  EXPECT_THROW(Pid({-1.0, 0.0, 0.0, 0.0}, 0.01, 0.0, 1.0), std::invalid_argument);
  EXPECT_THROW(Pid({1.0, 0.0, 0.0, 0.0}, 0.0, 0.0, 1.0), std::invalid_argument);
}

TEST(ScaleEstimatorTest, ConvergesAndFollowsFatigue) {
  // Noise-free regression τ_act = τ_scale·φ: RLS recovers τ_scale exactly;
  // after a 30 % drop (fatigue) it follows within a few 1/(1 − λ) windows.
  ScaleEstimator estimator(20.0, 0.99);
  double truth = 40.0;
  for (int k = 0; k < 1000; ++k) {
    const double phi = 0.3 + 0.2 * std::sin(0.05 * k);
    estimator.Update(phi, truth * phi);
  }
  EXPECT_NEAR(estimator.estimate_nm(), 40.0, 1e-6);
  truth = 28.0;
  int settled = -1;
  for (int k = 0; k < 2000; ++k) {
    const double phi = 0.3 + 0.2 * std::sin(0.05 * k);
    estimator.Update(phi, truth * phi);
    if (settled < 0 && std::abs(estimator.estimate_nm() - truth) < 0.01 * truth) settled = k;
  }
  EXPECT_GT(settled, 0);
  EXPECT_LT(settled, 5 * 100) << "within five forgetting windows (1/(1 − λ) = 100 samples)";
  EXPECT_NEAR(estimator.estimate_nm(), 28.0, 1e-6);
  // No information (no activation): the estimate stays.
  const double before = estimator.estimate_nm();
  EXPECT_DOUBLE_EQ(estimator.Update(0.0, 5.0), before);
  EXPECT_DOUBLE_EQ(estimator.Update(NAN, 5.0), before);
  EXPECT_THROW(ScaleEstimator(0.0, 0.99), std::invalid_argument);
  EXPECT_THROW(ScaleEstimator(10.0, 1.5), std::invalid_argument);
}

}  // namespace
}  // namespace fesbench::model
