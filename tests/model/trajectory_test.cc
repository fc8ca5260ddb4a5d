#include "model/trajectory.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace fesbench::model {
namespace {

// Central differences with h = 1e-4 s. Truncation error is h²/6·|θ'''|: with
// components up to 1 Hz and ±40° swing, |θ'''| ≲ 40·(2π)³ ≈ 1e4 deg/s³, so
// ≈ 2e-5 deg/s for velocity; for acceleration |θ''''| ≲ 40·(2π)⁴ ≈ 6e4 deg/s⁴
// gives ≈ 1e-4 deg/s². Round-off is ε·|θ|/h ≈ 1e-10. Tolerances 1e-4 deg/s
// and 1e-3 deg/s² are 5–10× above those bounds and ~1e-6 of the signals, so
// a wrong factor (2π, chain rule, fade derivative) fails clearly.
void ExpectDerivativesMatchFiniteDifferences(const Trajectory& tr, double step_s, double v_tol,
                                             double a_tol) {
  constexpr double h = 1e-4;
  for (double t = h; t < tr.duration_s() - h; t += step_s) {
    const Kinematics k = tr.At(t);
    const double fd_v = (tr.At(t + h).angle_deg - tr.At(t - h).angle_deg) / (2 * h);
    const double fd_a = (tr.At(t + h).velocity_deg_s - tr.At(t - h).velocity_deg_s) / (2 * h);
    ASSERT_NEAR(k.velocity_deg_s, fd_v, v_tol) << "t = " << t;
    ASSERT_NEAR(k.accel_deg_s2, fd_a, a_tol) << "t = " << t;
  }
}

TEST(SumOfSines, DerivativesAreAnalytic) {
  for (std::uint64_t seed : {1u, 2u, 99u}) {
    SumOfSinesOptions o;
    o.seed = seed;
    ExpectDerivativesMatchFiniteDifferences(SumOfSinesTrajectory(o), 0.0137, 1e-4, 1e-3);
  }
}

TEST(SumOfSines, StaysInRangeAndSpeedLimitAndCoversOne) {
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    for (const double v_max : {50.0, 200.0, 1000.0}) {
      SumOfSinesOptions o;
      o.seed = seed;
      o.min_deg = 35.0;
      o.max_deg = 105.0;
      o.max_velocity_deg_s = v_max;
      const SumOfSinesTrajectory tr(o);
      double lo = 1e9, hi = -1e9, v_peak = 0.0;
      for (int i = 0; i <= 10000; ++i) {
        const Kinematics k = tr.At(i * 1e-3);
        lo = std::min(lo, k.angle_deg);
        hi = std::max(hi, k.angle_deg);
        v_peak = std::max(v_peak, std::abs(k.velocity_deg_s));
      }
      EXPECT_GE(lo, 35.0);
      EXPECT_LE(hi, 105.0);
      EXPECT_LE(v_peak, v_max);
      // The binding limit is reached to within the 0.1 % margin (+ grid).
      const bool range_binds = hi - lo > 0.995 * 70.0;
      const bool speed_binds = v_peak > 0.995 * v_max;
      EXPECT_TRUE(range_binds || speed_binds) << "seed " << seed << " v_max " << v_max;
      if (v_max == 1000.0) {
        EXPECT_TRUE(range_binds);
      }
      if (v_max == 50.0) {
        EXPECT_TRUE(speed_binds);
      }
    }
  }
}

TEST(SumOfSines, StartsAndEndsAtRest) {
  const SumOfSinesTrajectory tr(SumOfSinesOptions{});
  for (const double t : {0.0, 10.0}) {
    const Kinematics k = tr.At(t);
    EXPECT_NEAR(k.angle_deg, tr.centre_deg(), 1e-9);
    EXPECT_NEAR(k.velocity_deg_s, 0.0, 1e-9);
    EXPECT_NEAR(k.accel_deg_s2, 0.0, 1e-9);
  }
  EXPECT_DOUBLE_EQ(tr.At(-1.0).angle_deg, tr.At(0.0).angle_deg);
  EXPECT_DOUBLE_EQ(tr.At(11.0).velocity_deg_s, 0.0);
  EXPECT_DOUBLE_EQ(tr.duration_s(), 10.0);
}

TEST(SumOfSines, SeededComponentsInTheirRanges) {
  SumOfSinesOptions o;
  o.seed = 5;
  const SumOfSinesTrajectory a(o), b(o);
  o.seed = 6;
  const SumOfSinesTrajectory c(o);
  ASSERT_EQ(a.components().size(), 6u);
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_EQ(a.components()[i].frequency_hz, b.components()[i].frequency_hz);
    EXPECT_EQ(a.components()[i].phase_rad, b.components()[i].phase_rad);
    EXPECT_NE(a.components()[i].frequency_hz, c.components()[i].frequency_hz);
    EXPECT_GE(a.components()[i].frequency_hz, 0.1);
    EXPECT_LE(a.components()[i].frequency_hz, 1.0);
    EXPECT_GE(a.components()[i].amplitude, 0.5);
    EXPECT_LE(a.components()[i].amplitude, 1.0);
  }
  EXPECT_EQ(a.At(3.3).angle_deg, b.At(3.3).angle_deg);
}

TEST(SumOfSines, RejectsBadOptions) {
  SumOfSinesOptions o;
  o.min_deg = 100.0;
  o.max_deg = 90.0;
  EXPECT_THROW(SumOfSinesTrajectory{o}, std::invalid_argument);
  o = {};
  o.fade_s = 6.0;
  EXPECT_THROW(SumOfSinesTrajectory{o}, std::invalid_argument);
}

TEST(PassivePositions, TwentyHoldsDownAndBack) {
  const SequentialPlan plan = PassivePositions({});
  ASSERT_EQ(plan.windows.size(), 40u);
  const double step = 80.0 / 19.0;
  for (std::size_t k = 0; k < 20; ++k) {
    EXPECT_NEAR(plan.windows[k].angle_deg, 110.0 - step * k, 1e-12);
    EXPECT_NEAR(plan.windows[39 - k].angle_deg, 110.0 - step * k, 1e-12);
  }
  for (const auto& w : plan.windows) {
    EXPECT_DOUBLE_EQ(w.end_s - w.start_s, 10.0);
    for (const double f : {0.0, 0.5, 0.999}) {
      const Kinematics k = plan.trajectory.At(w.start_s + f * (w.end_s - w.start_s));
      EXPECT_NEAR(k.angle_deg, w.angle_deg, 1e-9);
      EXPECT_DOUBLE_EQ(k.velocity_deg_s, 0.0);
    }
  }
  EXPECT_DOUBLE_EQ(plan.windows[0].start_s, 11.0);  // 10 s reference + 1 s move
  EXPECT_NEAR(plan.trajectory.duration_s(), 451.0, 1e-9);
  EXPECT_NEAR(plan.trajectory.At(0.0).angle_deg, 90.0, 1e-12);
  EXPECT_NEAR(plan.trajectory.At(451.0).angle_deg, 90.0, 1e-9);
  // Minimum-jerk moves: derivatives consistent and continuous. The jerk
  // jumps by up to 60·20°/1 s³ = 1200 deg/s³ where a move starts, so a
  // central difference straddling that instant is off by up to
  // 1200·h/4 = 0.03 deg/s²: tolerance 0.05.
  ExpectDerivativesMatchFiniteDifferences(plan.trajectory, 0.0731, 1e-4, 5e-2);
}

TEST(PassiveVelocities, EightSpeedsTwoDirections) {
  const SequentialPlan plan = PassiveVelocities({});
  ASSERT_EQ(plan.windows.size(), 16u);
  double min_angle = 1e9;
  for (int i = 0; i <= 200000; ++i)
    min_angle = std::min(min_angle, plan.trajectory.At(i * 1e-3).angle_deg);
  EXPECT_GE(min_angle, 30.0 - 1e-9);
  EXPECT_NEAR(min_angle, 90.0 - 30.0 * 1.75, 1e-6);  // fastest move covers 1.75·v
  for (std::size_t i = 0; i < 16; ++i) {
    const double speed = 30.0 * static_cast<double>(i / 2 + 1) / 8.0;
    const auto& w = plan.windows[i];
    EXPECT_DOUBLE_EQ(w.velocity_deg_s, i % 2 == 0 ? -speed : speed);
    EXPECT_NEAR(w.end_s - w.start_s, 1.0, 1e-12);
    for (const double f : {0.0, 0.5, 1.0}) {
      const Kinematics k = plan.trajectory.At(w.start_s + f * (w.end_s - w.start_s));
      EXPECT_NEAR(k.velocity_deg_s, w.velocity_deg_s, 1e-9);
      EXPECT_NEAR(k.accel_deg_s2, 0.0, 1e-9);
    }
  }
  // Each direction: 10 s pause, 1 s acceleration, then the window.
  EXPECT_NEAR(plan.windows[0].start_s, 11.0, 1e-12);
  EXPECT_NEAR(plan.windows[1].start_s, 11.0 + 1.0 + 0.5 + 10.0 + 1.0, 1e-12);
  EXPECT_NEAR(plan.trajectory.duration_s(), 200.0, 1e-9);
  EXPECT_NEAR(plan.trajectory.At(200.0).angle_deg, 90.0, 1e-9);
  // Jerk jumps by at most 6·30/0.5² = 720 deg/s³ (see above): 0.05 deg/s².
  ExpectDerivativesMatchFiniteDifferences(plan.trajectory, 0.0731, 1e-4, 5e-2);

  PassiveVelocitiesOptions o;
  o.max_speed_deg_s = 40.0;  // 1.75 · 40 = 70° > 60° available
  try {
    PassiveVelocities(o);
    ADD_FAILURE() << "expected a throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_speed_deg_s"), std::string::npos);
  }
}

TEST(PiecewisePolynomial, RejectsGaps) {
  using P = PiecewisePolynomialTrajectory::Piece;
  EXPECT_THROW(PiecewisePolynomialTrajectory({}), std::invalid_argument);
  EXPECT_THROW(PiecewisePolynomialTrajectory({P{0.0, 1.0, {}}, P{1.5, 1.0, {}}}),
               std::invalid_argument);
  EXPECT_THROW(PiecewisePolynomialTrajectory({P{0.0, 0.0, {}}}), std::invalid_argument);
  const PiecewisePolynomialTrajectory tr({P{0.0, 2.0, {1.0, 2.0, 3.0, 0, 0, 0}}});
  const Kinematics k = tr.At(1.0);
  EXPECT_DOUBLE_EQ(k.angle_deg, 6.0);
  EXPECT_DOUBLE_EQ(k.velocity_deg_s, 8.0);
  EXPECT_DOUBLE_EQ(k.accel_deg_s2, 6.0);
}

TEST(TrajectoryRegistry, MakesAndSamplesEveryGenerator) {
  ASSERT_EQ(TrajectoryGenerators().size(), 3u);
  for (const auto& d : TrajectoryGenerators()) {
    const auto tr = MakeTrajectory(d.name);
    ASSERT_NE(tr, nullptr);
    const TrajectorySamples s = SampleTrajectory(*tr);
    const auto n = static_cast<std::size_t>(std::floor(tr->duration_s() * 200.0 + 1e-9)) + 1;
    EXPECT_EQ(s.angle_deg.size(), n) << d.name;
    EXPECT_EQ(s.velocity_deg_s.size(), n);
    EXPECT_EQ(s.accel_deg_s2.size(), n);
    EXPECT_DOUBLE_EQ(s.angle_deg[7], tr->At(7 / 200.0).angle_deg);
  }
  EXPECT_EQ(SampleTrajectory(*MakeTrajectory("sum_of_sines")).angle_deg.size(), 2001u);
  // Same parameters, same trajectory; seed changes it.
  const auto a = MakeTrajectory("sum_of_sines", {{"seed", 3}, {"min_deg", 40}, {"max_deg", 95}});
  const auto b = MakeTrajectory("sum_of_sines", {{"seed", 3}, {"min_deg", 40}, {"max_deg", 95}});
  const auto c = MakeTrajectory("sum_of_sines", {{"seed", 4}, {"min_deg", 40}, {"max_deg", 95}});
  EXPECT_EQ(a->At(4.2).angle_deg, b->At(4.2).angle_deg);
  EXPECT_NE(a->At(4.2).angle_deg, c->At(4.2).angle_deg);
  EXPECT_THROW(MakeTrajectory("nope"), std::invalid_argument);
  try {
    MakeTrajectory("sum_of_sines", {{"min_deg", 100}, {"max_deg", 50}});
    ADD_FAILURE() << "expected a throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("min_deg"), std::string::npos);
  }
  EXPECT_THROW(MakeTrajectory("passive_positions", {{"hold_s", 0.0}}), std::invalid_argument);
  EXPECT_THROW(SampleTrajectory(*a, 0.0), std::invalid_argument);
}

}  // namespace
}  // namespace fesbench::model
