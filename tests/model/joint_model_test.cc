#include "model/joint_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "model/units.h"

namespace fesbench::model {
namespace {

TEST(JointModelTest, CurvePairTableMatchesPiecewiseLinear) {
  const PiecewiseLinear f({-400, -200, -50, 0, 10, 200}, {0.4, 0.7, 0.9, 1.0, 1.02, 1.3});
  const PiecewiseLinear g({-300, -100, 0, 100, 300}, {-1.0, 0.5, 0.0, 2.0, 2.5});
  const CurvePairTable table(f, g);
  const auto check = [](const CurvePairTable& t, const PiecewiseLinear& a, const PiecewiseLinear& b,
                        double x) {
    double fa = 0.0, gb = 0.0;
    t.Evaluate(x, fa, gb);
    EXPECT_NEAR(fa, a(x), 1e-12) << x;
    EXPECT_NEAR(gb, b(x), 1e-12) << x;
  };
  for (double x = -600.0; x <= 600.0; x += 0.37) check(table, f, g, x);
  for (double x : f.x()) check(table, f, g, x);
  for (double x : g.x()) check(table, f, g, x);
  // A constant partner adds no breakpoint; two constants still evaluate.
  const PiecewiseLinear one = PiecewiseLinear::Constant(1.0, 90.0);
  const CurvePairTable with_const(f, one);
  for (double x = -600.0; x <= 600.0; x += 7.1) check(with_const, f, one, x);
  const CurvePairTable constants(PiecewiseLinear::Constant(2.5), one);
  check(constants, PiecewiseLinear::Constant(2.5), one, -3.0);
  check(constants, PiecewiseLinear::Constant(2.5), one, 1e6);
  // Many breakpoints: the binary-search path.
  std::vector<double> y(60);
  for (std::size_t i = 0; i < y.size(); ++i) y[i] = std::sin(0.3 * static_cast<double>(i));
  const PiecewiseLinear dense = PiecewiseLinear::Uniform(0.0, 120.0, y);
  const CurvePairTable dense_table(dense, g);
  for (double x = -10.0; x <= 130.0; x += 0.53) check(dense_table, dense, g, x);
}

TEST(JointModelTest, FullModelEvaluatesItsCurves) {
  const ParameterSet p = ExampleParameterSet();
  const JointModel m = JointModel::FromParameters(p);
  EXPECT_EQ(m.kind(), ModelKind::kFull);
  EXPECT_EQ(m.inertia_kgm2(), 0.36);
  for (double th = 0.0; th <= 120.0; th += 3.3) {
    EXPECT_NEAR(m.PassiveAngleTorque(th), p.passive.torque_angle(th), 1e-12);
    EXPECT_NEAR(m.AngleGain(th), p.active.torque_angle(th), 1e-12);
  }
  for (double v = -500.0; v <= 500.0; v += 17.0) {
    EXPECT_NEAR(m.PassiveVelocityTorque(v), p.passive.torque_velocity(v), 1e-12);
    EXPECT_NEAR(m.VelocityGain(v), p.active.torque_velocity(v), 1e-12);
  }
  EXPECT_NEAR(m.ActiveGain(60.0, -30.0),
              40.0 * p.active.torque_angle(60.0) * p.active.torque_velocity(-30.0), 1e-12);
  // J·θ̈ = −τ_pta − τ_ptv − f_stim·gain, θ̈ in rad/s².
  const double acc = m.AccelerationDegS2(60.0, -30.0, 0.5, 2.0);
  EXPECT_NEAR(0.36 * DegToRad(acc),
              2.0 - p.passive.torque_angle(60.0) - p.passive.torque_velocity(-30.0) -
                  0.5 * m.ActiveGain(60.0, -30.0),
              1e-12);
}

TEST(JointModelTest, FullWithUnitGainsEqualsTorqueGenerator) {
  ParameterSet p = ExampleParameterSet();
  p.active.torque_angle = PiecewiseLinear::Constant(1.0, 90.0);
  p.active.torque_velocity = PiecewiseLinear::Constant(1.0, 0.0);
  const JointModel full = JointModel::FromParameters(p, ModelKind::kFull);
  const JointModel tg = JointModel::FromParameters(p, ModelKind::kTorqueGenerator);
  EXPECT_EQ(tg.kind(), ModelKind::kTorqueGenerator);
  for (double th = 5.0; th <= 115.0; th += 5.0) {
    for (double v = -300.0; v <= 300.0; v += 50.0) {
      EXPECT_EQ(full.ActiveGain(th, v), tg.ActiveGain(th, v));
      EXPECT_EQ(full.AccelerationDegS2(th, v, 0.3), tg.AccelerationDegS2(th, v, 0.3));
    }
  }
}

TEST(JointModelTest, SingleSegmentIdentityEqualsTorqueGenerator) {
  ParameterSet p = ExampleParameterSet();
  p.single_segment = {0.0, 1.0, 0.0, 1.0};
  const JointModel ss = JointModel::FromParameters(p, ModelKind::kSingleSegment);
  const JointModel tg = JointModel::FromParameters(p, ModelKind::kTorqueGenerator);
  for (double th = 5.0; th <= 115.0; th += 5.0) {
    for (double v = -300.0; v <= 300.0; v += 50.0) {
      EXPECT_EQ(ss.ActiveGain(th, v), tg.ActiveGain(th, v));
      EXPECT_EQ(ss.AccelerationDegS2(th, v, 0.7), tg.AccelerationDegS2(th, v, 0.7));
    }
  }
}

TEST(JointModelTest, SingleSegmentIsLinearAndClamped) {
  ParameterSet p = ExampleParameterSet();
  p.single_segment = {0.01, 0.2, 0.002, 1.0};  // Eqs. 5.1–5.2
  const JointModel m = JointModel::FromParameters(p, ModelKind::kSingleSegment);
  EXPECT_NEAR(m.AngleGain(50.0), 0.7, 1e-12);
  EXPECT_NEAR(m.VelocityGain(-100.0), 0.8, 1e-12);
  EXPECT_EQ(m.AngleGain(-40.0), 0.0);      // 0.01·(−40) + 0.2 < 0
  EXPECT_EQ(m.VelocityGain(-600.0), 0.0);  // 0.002·(−600) + 1 < 0
}

TEST(JointModelTest, StaticGainUsesOnlyVelocityCurve) {
  const ParameterSet p = ExampleParameterSet();
  const JointModel m = JointModel::FromParameters(p, ModelKind::kStaticGainPwlVelocity);
  EXPECT_EQ(m.AngleGain(30.0), 1.0);
  EXPECT_NEAR(m.VelocityGain(-150.0), p.active.torque_velocity(-150.0), 1e-12);
  EXPECT_NEAR(m.ActiveGain(30.0, -150.0), 40.0 * p.active.torque_velocity(-150.0), 1e-12);
}

TEST(JointModelTest, ParametricFormulas) {
  ParameterSet p = ExampleParameterSet();
  p.parametric = {8.6, 0.5, -3.0, -1.2, 65.0, 35.0, 0.0015, 0.0008};
  const JointModel m = JointModel::FromParameters(p, ModelKind::kParametric);
  const double th = DegToRad(40.0);
  // Eq. 7.3 plus the referencing offset.
  EXPECT_NEAR(m.PassiveAngleTorque(40.0), 8.6 * std::sin(th) + 0.5 * std::exp(-3.0 * th) - 1.2,
              1e-12);
  EXPECT_NEAR(m.AngleGain(90.0), 1.0, 1e-15);
  EXPECT_NEAR(m.AngleGain(65.0) / m.AngleGain(30.0), std::exp(35.0 * 35.0 / (2 * 35.0 * 35.0)),
              1e-12);
  EXPECT_NEAR(m.VelocityGain(-200.0), 1.0 - 0.3, 1e-12);
  EXPECT_NEAR(m.VelocityGain(100.0), 1.08, 1e-12);
  EXPECT_EQ(m.VelocityGain(-1000.0), 0.0);  // clamped
  EXPECT_NEAR(m.PassiveVelocityTorque(30.0), p.passive.torque_velocity(30.0), 1e-12);
}

TEST(JointModelTest, FullClampsNegativeGains) {
  ParameterSet p = ExampleParameterSet();
  p.active.torque_velocity = PiecewiseLinear({-100, 0}, {-0.5, 1.0});
  const JointModel m = JointModel::FromParameters(p);
  EXPECT_EQ(m.VelocityGain(-100.0), 0.0);
  EXPECT_NEAR(m.VelocityGain(-50.0), 0.25, 1e-12);
}

TEST(JointModelTest, RejectsInvalidParameters) {
  ParameterSet p = ExampleParameterSet();
  p.passive.inertia_kgm2 = 0.0;
  EXPECT_THROW(JointModel::FromParameters(p), std::invalid_argument);
  p = ExampleParameterSet();
  p.active.torque_scale_nm = -1.0;
  EXPECT_THROW(JointModel::FromParameters(p), std::invalid_argument);
  p = ExampleParameterSet();
  p.active.torque_angle = PiecewiseLinear();
  EXPECT_THROW(JointModel::FromParameters(p), std::invalid_argument);
  EXPECT_NO_THROW(JointModel::FromParameters(p, ModelKind::kStaticGainPwlVelocity));
  p = ExampleParameterSet();
  p.parametric.ata_width_deg = 0.0;
  EXPECT_THROW(JointModel::FromParameters(p, ModelKind::kParametric), std::invalid_argument);
  p = ExampleParameterSet();
  p.single_segment.a = NAN;
  EXPECT_THROW(JointModel::FromParameters(p, ModelKind::kSingleSegment), std::invalid_argument);
}

}  // namespace
}  // namespace fesbench::model
