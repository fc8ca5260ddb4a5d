#include "model/parameter_set.h"

#include <gtest/gtest.h>

namespace fesbench::model {
namespace {

TEST(ParameterSet, ModelKindNamesRoundTrip) {
  for (ModelKind k : AllModelKinds()) {
    const auto parsed = ParseModelKind(ModelKindName(k));
    ASSERT_TRUE(parsed.has_value());
    EXPECT_EQ(*parsed, k);
  }
  EXPECT_FALSE(ParseModelKind("hill").has_value());
  EXPECT_EQ(AllModelKinds().size(), 5u);
}

TEST(ParameterSet, ReferencingKeepsThePassiveSum) {
  // §6.5: only τ_pta + τ_ptv is identifiable; referencing must not change it.
  PassiveParams p;
  p.torque_angle = PiecewiseLinear({10, 50, 110}, {-5.0, 1.0, 7.0});
  p.torque_velocity = PiecewiseLinear({-100, 0, 100}, {-1.0, 0.0, 1.5});
  const PassiveParams r = ReferencePassive(p);
  EXPECT_NEAR(r.torque_angle(kReferenceAngleDeg), 0.0, 1e-12);
  for (double th : {10.0, 33.0, 90.0, 110.0}) {
    for (double v : {-100.0, -7.0, 0.0, 42.0}) {
      EXPECT_NEAR(r.torque_angle(th) + r.torque_velocity(v),
                  p.torque_angle(th) + p.torque_velocity(v), 1e-12);
    }
  }
  EXPECT_NEAR(r.torque_velocity(0.0), 5.0, 1e-12);  // τ_pta(90°) moved into τ_ptv
}

TEST(ParameterSet, NormalisationKeepsTheActiveProduct) {
  ActiveParams a;
  a.torque_scale_nm = 10.0;
  a.torque_angle = PiecewiseLinear({10, 90, 110}, {1.0, 2.0, 0.5});
  a.torque_velocity = PiecewiseLinear({-100, 0, 100}, {1.0, 4.0, 5.0});
  const ActiveParams n = NormaliseActive(a);
  EXPECT_NEAR(n.torque_angle(90.0), 1.0, 1e-12);
  EXPECT_NEAR(n.torque_velocity(0.0), 1.0, 1e-12);
  EXPECT_NEAR(n.torque_scale_nm, 80.0, 1e-12);
  for (double th : {10.0, 50.0, 105.0}) {
    for (double v : {-100.0, -20.0, 60.0}) {
      EXPECT_NEAR(n.torque_scale_nm * n.torque_angle(th) * n.torque_velocity(v),
                  a.torque_scale_nm * a.torque_angle(th) * a.torque_velocity(v), 1e-9);
    }
  }
  a.torque_angle = PiecewiseLinear({10, 90}, {1.0, 0.0});
  EXPECT_THROW(NormaliseActive(a), std::invalid_argument);
}

TEST(ParameterSet, ExampleIsReferencedAndNormalised) {
  const ParameterSet p = ExampleParameterSet();
  EXPECT_NEAR(p.passive.torque_angle(90.0), 0.0, 1e-12);
  EXPECT_NEAR(p.active.torque_angle(90.0), 1.0, 1e-12);
  EXPECT_NEAR(p.active.torque_velocity(0.0), 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(p.irc(10.0), 0.0);
  EXPECT_DOUBLE_EQ(p.irc(60.0), 1.0);
  // The passive torque is a restoring torque about a rest angle near 81°.
  EXPECT_LT(p.passive.torque_angle(60.0), p.passive.torque_angle(81.0));
  EXPECT_GT(p.passive.torque_angle(100.0), p.passive.torque_angle(81.0));
}

}  // namespace
}  // namespace fesbench::model
