#include "model/integrators.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <stdexcept>

namespace fesbench::model {
namespace {

using Vec1 = Eigen::Matrix<double, 1, 1>;
using Vec2 = Eigen::Vector2d;

// ẏ = y·cos t, y(0) = 1  →  y = e^(sin t).
const auto kSinExp = [](double t, const Vec1& y) { return Vec1(y[0] * std::cos(t)); };

double Rk4Error(double h) {
  const Vec1 y = IntegrateRk4(kSinExp, 0.0, 2.0, Vec1(1.0), h);
  return std::abs(y[0] - std::exp(std::sin(2.0)));
}

TEST(IntegratorsTest, Rk4IsFourthOrder) {
  const double e1 = Rk4Error(0.1), e2 = Rk4Error(0.05), e3 = Rk4Error(0.025);
  EXPECT_NEAR(e1 / e2, 16.0, 1.5);
  EXPECT_NEAR(e2 / e3, 16.0, 1.0);
  EXPECT_LT(e3, 1e-7);
}

TEST(IntegratorsTest, Rk4SplitsIntoEqualSteps) {
  IntegrationStats stats;
  IntegrateRk4(kSinExp, 0.0, 0.005, Vec1(1.0), 0.001, &stats);
  EXPECT_EQ(stats.accepted_steps, 5);
  EXPECT_EQ(stats.rhs_evaluations, 20);
  EXPECT_EQ(EvenStepCount(0.0031, 0.001), 4);
}

// Harmonic oscillator ẍ = −ω²x, x(0) = 1, ẋ(0) = 0  →  x = cos ωt.
TEST(IntegratorsTest, DormandPrinceMeetsTolerance) {
  const double w = 3.0;
  const auto f = [w](double, const Vec2& x) { return Vec2(x[1], -w * w * x[0]); };
  for (double tol : {1e-6, 1e-9}) {
    AdaptiveTolerances t;
    t.rtol = tol;
    t.atol = tol;
    IntegratorWorkspace ws;
    const Vec2 x = IntegrateDormandPrince45(f, 0.0, 10.0, Vec2(1.0, 0.0), t, ws);
    // Global error after ~5 periods stays within a small multiple of the
    // local tolerance.
    EXPECT_NEAR(x[0], std::cos(w * 10.0), 20 * tol) << tol;
    EXPECT_NEAR(x[1], -w * std::sin(w * 10.0), 60 * tol) << tol;
    EXPECT_GT(ws.stats.accepted_steps, 10);
    EXPECT_GT(ws.next_step_s, 0.0);
  }
}

TEST(IntegratorsTest, DormandPrinceRejectsStepsOnAFastTransient) {
  // ẏ = −k(y − sin t) with a fast pole, started far from the slow manifold,
  // and a deliberately large first step: the controller must reject it.
  const double k = 200.0;
  const auto f = [k](double t, const Vec1& y) { return Vec1(-k * (y[0] - std::sin(t))); };
  AdaptiveTolerances tol;
  tol.rtol = 1e-9;
  tol.atol = 1e-9;
  IntegratorWorkspace ws;
  ws.next_step_s = 0.05;
  const Vec1 y = IntegrateDormandPrince45(f, 0.0, 1.0, Vec1(1.0), tol, ws);
  // Closed form: y = A·sin t + B·cos t + C·e^(−kt).
  const double a = k * k / (k * k + 1), b = -k / (k * k + 1), c = 1.0 - b;
  EXPECT_NEAR(y[0], a * std::sin(1.0) + b * std::cos(1.0) + c * std::exp(-k), 1e-7);
  EXPECT_GT(ws.stats.rejected_steps, 0);
}

TEST(IntegratorsTest, DormandPrinceThrowsBelowMinimumStep) {
  const auto f = [](double, const Vec1& y) { return Vec1(1e6 * y[0] * y[0]); };  // blows up
  AdaptiveTolerances tol;
  tol.min_step_s = 1e-6;
  IntegratorWorkspace ws;
  EXPECT_THROW(IntegrateDormandPrince45(f, 0.0, 1.0, Vec1(1.0), tol, ws), std::runtime_error);
}

TEST(IntegratorsTest, IntegrateDispatchesOnKind) {
  const auto f = [](double, const Vec2& x) { return Vec2(x[1], -x[0]); };
  IntegratorSettings rk4{IntegratorKind::kRk4, 1e-3, {}};
  IntegratorSettings dp{IntegratorKind::kAdaptive, 1e-3, {1e-10, 1e-10, 1e-12, 0.1, 100000}};
  IntegratorWorkspace w1, w2;
  const Vec2 a = Integrate(f, 0.0, 1.0, Vec2(1.0, 0.0), rk4, w1);
  const Vec2 b = Integrate(f, 0.0, 1.0, Vec2(1.0, 0.0), dp, w2);
  EXPECT_NEAR(a[0], std::cos(1.0), 1e-12);
  EXPECT_NEAR(b[0], std::cos(1.0), 1e-9);
  EXPECT_EQ(w1.stats.accepted_steps, 1000);
  EXPECT_LT(w2.stats.accepted_steps, 200);
}

TEST(IntegratorsTest, NamesAndValidation) {
  EXPECT_EQ(IntegratorKindName(IntegratorKind::kRk4), "rk4");
  EXPECT_EQ(ParseIntegratorKind("adaptive"), IntegratorKind::kAdaptive);
  EXPECT_FALSE(ParseIntegratorKind("euler").has_value());
  AdaptiveTolerances t;
  t.rtol = 0.0;
  EXPECT_THROW(ValidateTolerances(t), std::invalid_argument);
  t = {};
  t.max_step_s = t.min_step_s / 2;
  EXPECT_THROW(ValidateTolerances(t), std::invalid_argument);
  IntegratorSettings s;
  s.step_s = NAN;
  EXPECT_THROW(ValidateIntegratorSettings(s), std::invalid_argument);
}

}  // namespace
}  // namespace fesbench::model
