#include "model/conditioning.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace fesbench::model {
namespace {

TEST(TorqueOffset, MeansTheFirstSamples) {
  std::vector<double> tq(100, 5.0);
  for (int i = 0; i < 50; ++i) tq[static_cast<std::size_t>(i)] = 1.0 + (i % 2 ? 0.1 : -0.1);
  EXPECT_NEAR(TorqueOffset(tq), 1.0, 1e-12);
  EXPECT_NEAR(RemoveTorqueOffset(tq)[99], 4.0, 1e-12);
  EXPECT_THROW(TorqueOffset(std::vector<double>(10, 0.0)), std::invalid_argument);
}

TEST(AccelerometerCalibration, TableFromHoldsRemovesGravity) {
  // Holds at 110, 90, …, 30 deg then back; the sensor reads g·cos-like
  // gravity plus a reading that differs slightly by direction.
  const double rate = 200.0;
  std::vector<double> t, ang, acc;
  const auto gravity = [](double th) { return 300.0 * std::cos(th * M_PI / 180.0); };
  std::vector<double> levels;
  for (double a = 110; a >= 30; a -= 20) levels.push_back(a);
  for (double a = 30; a <= 110; a += 20) levels.push_back(a);
  double th = levels.front();
  for (std::size_t k = 0; k < levels.size(); ++k) {
    // Direction-dependent bias, averaged out (30 deg is one merged hold).
    const double bias = levels[k] == 30.0 ? 0.0 : (k < 5 ? 2.0 : -2.0);
    for (int i = 0; i < 400; ++i) {  // 0.5 s move, 1.5 s hold
      if (i < 100)
        th += (levels[k] - th) * 0.05;
      else
        th = levels[k];
      t.push_back(static_cast<double>(t.size()) / rate);
      ang.push_back(th);
      acc.push_back(gravity(th) + (i >= 100 ? bias : 50.0));
    }
  }
  const PiecewiseLinear table = AccelerometerCalibration(t, ang, acc);
  ASSERT_EQ(table.size(), 5u);
  for (double a = 30; a <= 110; a += 20) EXPECT_NEAR(table(a), gravity(a), 1e-9) << a;
  const std::vector<double> a_in = {50.0, 70.0};
  const std::vector<double> r_in = {gravity(50.0) + 12.0, gravity(70.0) - 3.0};
  const auto corrected = CorrectAcceleration(table, a_in, r_in);
  EXPECT_NEAR(corrected[0], 12.0, 1e-9);
  EXPECT_NEAR(corrected[1], -3.0, 1e-9);
}

TEST(DetectHolds, FindsHoldsInNoisyQuantisedPotentiometerData) {
  // §5.4.1 position holds as the bench records them: 12-bit angle
  // (120°/4096 per LSB) with ±0.03° noise. Neighbouring samples then differ
  // by up to a few deg/s, which must not hide a 10 s hold.
  const double rate = 200.0, lsb = 120.0 / 4096.0;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> noise(-0.03, 0.03);
  std::vector<double> t, ang;
  const std::vector<double> levels = {110.0, 90.0, 70.0, 50.0};
  double th = 90.0;
  for (double level : levels) {
    for (int i = 0; i < 200; ++i) {  // 1 s move at constant speed
      th += (level - th) / static_cast<double>(200 - i);
      t.push_back(static_cast<double>(t.size()) / rate);
      ang.push_back(std::round((th + noise(rng)) / lsb) * lsb);
    }
    for (int i = 0; i < 2000; ++i) {  // 10 s hold
      t.push_back(static_cast<double>(t.size()) / rate);
      ang.push_back(std::round((level + noise(rng)) / lsb) * lsb);
    }
  }
  const auto holds = DetectHolds(t, ang, {}, {}, HoldOptions{});
  ASSERT_EQ(holds.size(), levels.size());
  for (std::size_t k = 0; k < levels.size(); ++k) {
    EXPECT_NEAR(holds[k].angle_deg, levels[k], 0.03) << k;
    EXPECT_GT(t[holds[k].end - 1] - t[holds[k].begin], 9.0) << k;
  }
}

TEST(SmoothingSpline, ZeroLambdaInterpolatesAndLargeLambdaIsALine) {
  std::vector<double> t, y;
  for (int i = 0; i < 30; ++i) {
    t.push_back(i * 0.01 + (i % 3) * 1e-3);
    y.push_back(std::sin(7.0 * t.back()) + (i % 2 ? 0.1 : -0.1));
  }
  const auto interp = SmoothingSpline(t, y, 0.0);
  for (std::size_t i = 0; i < t.size(); ++i) EXPECT_NEAR(interp.value[i], y[i], 1e-9);
  EXPECT_NEAR(interp.effective_dof, 30.0, 1e-6);
  // λ → ∞: least-squares straight line, 2 degrees of freedom.
  const auto line = SmoothingSpline(t, y, 1e12);
  EXPECT_NEAR(line.effective_dof, 2.0, 1e-3);
  for (std::size_t i = 0; i < t.size(); ++i) EXPECT_NEAR(line.second[i], 0.0, 1e-6);
  for (std::size_t i = 1; i < t.size(); ++i) {
    EXPECT_NEAR(line.first[i], line.first[0], 1e-5);
  }
}

TEST(SmoothingSpline, CubicIsReproducedExactlyWithDerivatives) {
  // A natural spline cannot bend at its ends, but a straight line plus any
  // λ stays exact; a quadratic is exact at λ = 0 away from the ends.
  std::vector<double> t, y;
  for (int i = 0; i < 50; ++i) {
    t.push_back(0.02 * i);
    y.push_back(3.0 - 2.0 * t.back());
  }
  const auto fit = SmoothingSpline(t, y, 5.0);
  for (std::size_t i = 0; i < t.size(); ++i) {
    EXPECT_NEAR(fit.value[i], y[i], 1e-9);
    EXPECT_NEAR(fit.first[i], -2.0, 1e-8);
  }
}

TEST(GcvSmoothingSpline, DifferentiatesNoisyPositionNearTheTruth) {
  // θ(t) = 40 sin(2π·0.8 t) + 60 deg, 200 Hz, white noise σ = 0.2 deg.
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.2);
  const double w = 2.0 * M_PI * 0.8;
  std::vector<double> t, y;
  for (int i = 0; i < 2000; ++i) {
    t.push_back(i / 200.0);
    y.push_back(60.0 + 40.0 * std::sin(w * t.back()) + noise(rng));
  }
  const auto fit = GcvSmoothingSpline(t, y);
  double e0 = 0, e1 = 0, e2 = 0;
  int cnt = 0;
  for (std::size_t i = 100; i + 100 < t.size(); ++i) {  // away from natural ends
    const double tt = t[i];
    e0 += std::pow(fit.value[i] - (60.0 + 40.0 * std::sin(w * tt)), 2);
    e1 += std::pow(fit.first[i] - 40.0 * w * std::cos(w * tt), 2);
    e2 += std::pow(fit.second[i] + 40.0 * w * w * std::sin(w * tt), 2);
    ++cnt;
  }
  // Velocity amplitude ≈ 201 deg/s, acceleration ≈ 1011 deg/s².
  EXPECT_LT(std::sqrt(e0 / cnt), 0.1);       // below the 0.2 deg noise
  EXPECT_LT(std::sqrt(e1 / cnt), 2.0);       // < 1 % of amplitude
  EXPECT_LT(std::sqrt(e2 / cnt), 50.0);      // < 5 % of amplitude
  EXPECT_NEAR(fit.residual_rms, 0.2, 0.02);  // GCV leaves the noise out
  EXPECT_GT(fit.effective_dof, 4.0);
  EXPECT_LT(fit.effective_dof, 250.0);
  // GCV is a minimum: a λ ten times either way scores worse.
  EXPECT_GT(SmoothingSpline(t, y, fit.lambda * 10).gcv, fit.gcv);
  EXPECT_GT(SmoothingSpline(t, y, fit.lambda / 10).gcv, fit.gcv);
}

TEST(SmoothingSpline, RejectsBadInput) {
  const std::vector<double> t = {0, 1, 2}, y = {0, 1, 2};
  EXPECT_THROW(SmoothingSpline(t, y, 1.0), std::invalid_argument);
  const std::vector<double> t4 = {0, 1, 1, 2}, y4 = {0, 1, 2, 3};
  EXPECT_THROW(SmoothingSpline(t4, y4, 1.0), std::invalid_argument);
  const std::vector<double> t5 = {0, 1, 2, 3};
  EXPECT_THROW(SmoothingSpline(t5, y4, -1.0), std::invalid_argument);
}

}  // namespace
}  // namespace fesbench::model
