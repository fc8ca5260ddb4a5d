#include "model/evaluation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "model/units.h"

namespace fesbench::model {
namespace {

// Hand-computed example: differences 0.1, −0.2, 0.4, 0.3 (Σe² = 0.30,
// Σ|e| = 1.0, Σdata = 7).
const std::vector<double> kData = {1.0, 2.0, 4.0, 0.0};
const std::vector<double> kPred = {1.1, 1.8, 4.4, 0.3};

TEST(Errors, RmsAndAbsOnHandExample) {
  EXPECT_NEAR(RmsError(kPred, kData), std::sqrt(0.30 / 4.0), 1e-12);  // Eq. 6.9: 0.273861
  EXPECT_NEAR(AbsError(kPred, kData), 0.25, 1e-12);                   // Eq. 6.10
  EXPECT_DOUBLE_EQ(RmsError(kData, kData), 0.0);
}

TEST(Errors, NormalisedRmsExcludesZeroData) {
  // Relative errors 0.1, −0.1, 0.1; the sample with data 0 is excluded.
  const NormalisedRms r = NormalisedRmsError(kPred, kData).value();
  EXPECT_NEAR(r.value, 0.1, 1e-12);
  EXPECT_EQ(r.samples_used, 3u);
  EXPECT_EQ(r.samples_excluded, 1u);
  // With a 30 % floor (1.2 of max 4) the sample with data 1 goes too:
  // relative errors −0.1, 0.1 → 0.1. The floor is inclusive: data 0.2 with
  // max 4 and 5 % is excluded, data 0.25 is kept (relative error 0.4).
  const NormalisedRms r30 = NormalisedRmsError(kPred, kData, 0.3).value();
  EXPECT_EQ(r30.samples_used, 2u);
  EXPECT_NEAR(r30.value, 0.1, 1e-12);
  const std::vector<double> d2 = {0.2, 4.0}, p2 = {0.3, 4.4};
  EXPECT_EQ(NormalisedRmsError(p2, d2)->samples_used, 1u);
  EXPECT_NEAR(NormalisedRmsError(p2, d2)->value, 0.1, 1e-12);
  const std::vector<double> d3 = {0.25, 4.0}, p3 = {0.35, 4.0};
  EXPECT_NEAR(NormalisedRmsError(p3, d3)->value, std::sqrt(0.16 / 2.0), 1e-12);
  const std::vector<double> zeros = {0.0, 0.0};
  EXPECT_FALSE(NormalisedRmsError(p2, zeros).has_value());  // Eq. 6.1 undefined
}

TEST(Errors, AveragedRms) {
  EXPECT_NEAR(AveragedRmsError(kPred, kData).value(), std::sqrt(0.30) / 7.0, 1e-12);  // Eq. 6.2: 0.078246
  const std::vector<double> zero_sum = {1.0, -1.0};
  EXPECT_FALSE(AveragedRmsError(zero_sum, zero_sum).has_value());  // Eq. 6.2 undefined
}

TEST(Errors, RejectBadInput) {
  const std::vector<double> one = {1.0};
  const std::vector<double> empty;
  const std::vector<double> nan = {NAN};
  EXPECT_THROW(RmsError(kPred, one), std::invalid_argument);
  EXPECT_THROW(AbsError(empty, empty), std::invalid_argument);
  EXPECT_THROW(RmsError(nan, one), std::invalid_argument);
  EXPECT_THROW(NormalisedRmsError(kPred, kData, 1.0), std::invalid_argument);
}

TEST(PairedTTest, StudentSleepData) {
  // Student (1908), "The probable error of a mean", Biometrika 6:1-25: extra
  // hours of sleep of 10 patients under two drugs (Cushny & Peebles), the R
  // data set `sleep`. R's t.test(extra ~ group, data = sleep, paired = TRUE)
  // reports t = -4.0621, df = 9, p-value = 0.002833, mean difference -1.58.
  const std::vector<double> drug1 = {0.7, -1.6, -0.2, -1.2, -0.1, 3.4, 3.7, 0.8, 0.0, 2.0};
  const std::vector<double> drug2 = {1.9, 0.8, 1.1, 0.1, -0.1, 4.4, 5.5, 1.6, 4.6, 3.4};
  const PairedTTestResult r = PairedTTest(drug1, drug2);
  EXPECT_EQ(r.n, 10u);
  EXPECT_DOUBLE_EQ(r.df, 9.0);
  EXPECT_NEAR(r.mean_difference, -1.58, 1e-12);
  EXPECT_NEAR(r.sd_difference, 1.229995, 1e-6);
  EXPECT_NEAR(r.t, -4.0621, 5e-5);
  EXPECT_NEAR(r.p_value, 0.002833, 5e-7);
  EXPECT_NEAR(r.t_critical, 2.262157, 1e-6);  // t_{0.975, 9}
  EXPECT_TRUE(r.significant);
  // Swapping the groups flips the sign only.
  const PairedTTestResult s = PairedTTest(drug2, drug1);
  EXPECT_NEAR(s.t, -r.t, 1e-12);
  EXPECT_NEAR(s.p_value, r.p_value, 1e-15);
}

TEST(PairedTTest, CriticalValuesAndInsignificance) {
  EXPECT_NEAR(StudentTCritical(15), 2.131, 5e-4);
  EXPECT_NEAR(StudentTCritical(45), 2.014, 5e-4);  // §6.1.2 quotes 2.02 for n = 46
  EXPECT_NEAR(StudentTCritical(1e6), 1.959964, 1e-5);
  // Differences 1, −1, 2, −2, 0.5: d̄ = 0.1, small t, not significant.
  const std::vector<double> a = {1, -1, 2, -2, 0.5}, b = {0, 0, 0, 0, 0};
  const PairedTTestResult r = PairedTTest(a, b);
  EXPECT_NEAR(r.mean_difference, 0.1, 1e-12);
  EXPECT_NEAR(r.t, 0.1 / (std::sqrt(10.2 / 4.0) / std::sqrt(5.0)), 1e-12);
  EXPECT_FALSE(r.significant);
  EXPECT_GT(r.p_value, 0.85);  // t = 0.140, df 4: p ≈ 0.895
  EXPECT_LT(r.p_value, 0.95);
  const std::vector<double> same = {1, 1, 1};
  const std::vector<double> shifted = {2, 2, 2};
  EXPECT_THROW(PairedTTest(same, shifted), std::invalid_argument);  // S_d = 0
  EXPECT_THROW(PairedTTest(std::vector<double>{1.0}, std::vector<double>{2.0}),
               std::invalid_argument);
  EXPECT_THROW(StudentTCritical(0.0), std::invalid_argument);
}

// A linear spring-damper-inertia system J·θ̈ + b·θ̇ + k·(θ − θ₀) = 0, written
// as PWL curves per degree.
PassiveParams LinearSystem(double j, double k_per_rad, double b_per_rad, double rest_deg) {
  PassiveParams p;
  p.inertia_kgm2 = j;
  const double k = k_per_rad * kRadPerDeg, b = b_per_rad * kRadPerDeg;
  p.torque_angle = PiecewiseLinear({0.0, 60.0, 120.0},
                                   {k * (0 - rest_deg), k * (60 - rest_deg), k * (120 - rest_deg)});
  p.torque_velocity = PiecewiseLinear({-500.0, 0.0, 500.0}, {-500.0 * b, 0.0, 500.0 * b});
  return p;
}

TEST(LinearisePassive, RecoversSpringDamperInertia) {
  const double j = 0.36, k = 30.0, b = 1.2;
  const PassiveLinearisation l = LinearisePassive(LinearSystem(j, k, b, 70.0), 81.0, 0.0);
  EXPECT_NEAR(l.stiffness_nm_per_rad, k, 1e-9);
  EXPECT_NEAR(l.damping_nm_s_per_rad, b, 1e-9);
  const double wn = std::sqrt(k / j);              // 9.128709 rad/s
  const double zeta = b / (2 * std::sqrt(k * j));  // 0.182574
  EXPECT_NEAR(l.natural_frequency_rad_s, wn, 1e-9);
  EXPECT_NEAR(l.damping_ratio, zeta, 1e-9);
  ASSERT_TRUE(l.damped_period_s.has_value());
  EXPECT_NEAR(*l.damped_period_s, 2 * kPi / (wn * std::sqrt(1 - zeta * zeta)), 1e-9);

  // Independent check of T and M2/M1: integrate the linear ODE (RK4,
  // dt = 1e-4 s, error ~1e-12) from a 10° displacement and measure the
  // time between the first two velocity zero-crossings (half a period) and
  // the ratio of the displacement magnitudes there. Linear interpolation of
  // the crossing (velocity is locally linear there) errs by ~1e-8 s.
  double th = 10.0 * kRadPerDeg, w = 0.0, t = 0.0;
  const double dt = 1e-4;
  auto f = [&](double x, double v) { return -(b * v + k * x) / j; };
  std::vector<double> peak_t, peak_x;
  while (peak_t.size() < 2 && t < 5.0) {
    const double k1x = w, k1v = f(th, w);
    const double k2x = w + 0.5 * dt * k1v, k2v = f(th + 0.5 * dt * k1x, w + 0.5 * dt * k1v);
    const double k3x = w + 0.5 * dt * k2v, k3v = f(th + 0.5 * dt * k2x, w + 0.5 * dt * k2v);
    const double k4x = w + dt * k3v, k4v = f(th + dt * k3x, w + dt * k3v);
    const double th1 = th + dt / 6 * (k1x + 2 * k2x + 2 * k3x + k4x);
    const double w1 = w + dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v);
    if (t > 0 && ((w < 0 && w1 >= 0) || (w > 0 && w1 <= 0))) {
      const double frac = w / (w - w1);  // linear interpolation of the zero
      peak_t.push_back(t + frac * dt);
      peak_x.push_back(th + frac * (th1 - th));
    }
    th = th1;
    w = w1;
    t += dt;
  }
  ASSERT_EQ(peak_t.size(), 2u);
  EXPECT_NEAR(peak_t[1] - peak_t[0], 0.5 * *l.damped_period_s, 1e-6);
  ASSERT_TRUE(l.peak_ratio.has_value());
  EXPECT_NEAR(std::abs(peak_x[1] / peak_x[0]), *l.peak_ratio, 1e-6);
}

TEST(LinearisePassive, Table6_4SimultaneousRow) {
  // Table 6.4: ζ 0.137, ω_n 5.190 rad/s → 0.5T = 0.61 s, M2/M1 = 0.64
  // (exp(−πζ/√(1−ζ²)) = 0.6476: the table truncates).
  const double j = 0.36, wn = 5.190, zeta = 0.137;
  const double k = wn * wn * j, b = 2 * zeta * std::sqrt(k * j);
  const PassiveLinearisation l = LinearisePassive(LinearSystem(j, k, b, 81.0), 81.0, 0.0);
  EXPECT_NEAR(l.natural_frequency_rad_s, wn, 1e-9);
  EXPECT_NEAR(l.damping_ratio, zeta, 1e-9);
  EXPECT_NEAR(0.5 * *l.damped_period_s, 0.61, 0.005);
  EXPECT_NEAR(*l.peak_ratio, 0.64, 0.01);
}

TEST(LinearisePassive, SidesAtBreakpointAndOverdamped) {
  PassiveParams p = LinearSystem(0.36, 30.0, 1.2, 70.0);
  // Asymmetric τ_ptv: 0.01 N·m/(deg/s) for θ̇ < 0, 0.03 for θ̇ > 0.
  p.torque_velocity = PiecewiseLinear({-100.0, 0.0, 100.0}, {-1.0, 0.0, 3.0});
  LinearisationOptions o;
  o.velocity_side = SlopeSide::kLeft;
  EXPECT_NEAR(LinearisePassive(p, 80.0, 0.0, o).damping_nm_s_per_rad, 0.01 * kDegPerRad, 1e-12);
  o.velocity_side = SlopeSide::kRight;
  EXPECT_NEAR(LinearisePassive(p, 80.0, 0.0, o).damping_nm_s_per_rad, 0.03 * kDegPerRad, 1e-12);
  EXPECT_NEAR(LinearisePassive(p, 80.0, 0.0).damping_nm_s_per_rad, 0.02 * kDegPerRad, 1e-12);
  // ζ ≥ 1: no period, no overshoot.
  const PassiveLinearisation over = LinearisePassive(LinearSystem(0.36, 30.0, 10.0, 70.0), 70.0, 0);
  EXPECT_GT(over.damping_ratio, 1.0);
  EXPECT_FALSE(over.damped_period_s.has_value());
  EXPECT_FALSE(over.peak_ratio.has_value());
  // Negative stiffness: no oscillator.
  PassiveParams unstable = p;
  unstable.torque_angle = PiecewiseLinear({0.0, 120.0}, {5.0, -5.0});
  EXPECT_THROW(LinearisePassive(unstable, 60.0, 0.0), std::invalid_argument);
}

TEST(PassiveRestAngle, FindsStableZero) {
  EXPECT_NEAR(PassiveRestAngle(LinearSystem(0.36, 30.0, 1.2, 70.0)), 70.0, 1e-9);
  // Referenced curves (§6.5): τ_pta(90°) = 0 and the constant c sits in
  // τ_ptv(0); the rest angle solves τ_pta(θ) = −c: k·(θ − 90) = −10·k.
  PassiveParams p = LinearSystem(0.36, 30.0, 1.2, 90.0);
  const double k_per_deg = 30.0 * kRadPerDeg;
  p.torque_velocity = p.torque_velocity.Shifted(k_per_deg * 10.0);
  EXPECT_NEAR(PassiveRestAngle(p), 80.0, 1e-9);
  // Nonlinear τ_pta with two stable zeros (40° and 100°) and an unstable one
  // (70°): the nearest stable one to the hint wins.
  PassiveParams two = p;
  two.torque_velocity = PiecewiseLinear({0.0}, {0.0});
  two.torque_angle = PiecewiseLinear({20, 60, 80, 120}, {-2.0, 2.0, -2.0, 2.0});
  EXPECT_NEAR(PassiveRestAngle(two, 90.0), 100.0, 1e-12);
  EXPECT_NEAR(PassiveRestAngle(two, 50.0), 40.0, 1e-12);
  EXPECT_NEAR(FindPassiveRestAngle(two, 50.0).value(), 40.0, 1e-12);
  two.torque_angle = PiecewiseLinear({20, 120}, {2.0, -2.0});
  EXPECT_THROW(PassiveRestAngle(two), std::invalid_argument);
  EXPECT_FALSE(FindPassiveRestAngle(two).has_value());
}

}  // namespace
}  // namespace fesbench::model
