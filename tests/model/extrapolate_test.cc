// Curves beyond their data (model/extrapolate.h) against closed forms: a
// pure gravity + exponential end-range leg fitted on a sub-range and
// extrapolated; Gaussian f_ata never rising; velocity curves continued; the
// share of a trajectory outside the identified ranges.
#include "model/extrapolate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "model/units.h"

namespace fesbench::model {
namespace {

// τ(θ) = mgl·sin(θ − θ_h) − k_e·e^(−(θ − 10)/w_e) + k_f·e^((θ − 110)/w_f).
struct Leg {
  double mgl = 10.0, hang = 81.0, ke = 4.0, we = 11.0, kf = 3.0, wf = 15.0;
  double operator()(double th) const {
    return mgl * std::sin(DegToRad(th - hang)) - ke * std::exp(-(th - 10.0) / we) +
           kf * std::exp((th - 110.0) / wf);
  }
};

PiecewiseLinear Tabulate(const auto& f, double lo, double hi, double step) {
  std::vector<double> x, y;
  for (double th = lo; th <= hi + 1e-9; th += step) x.push_back(th), y.push_back(f(th));
  return PiecewiseLinear(x, y);
}

TEST(Extrapolate, GravityPlusExponentialLegFromASubRange) {
  const Leg leg;
  // Identified over 30–100° only (every 1°, as a dense PWL fit would give).
  const PiecewiseLinear fitted = Tabulate(leg, 30.0, 100.0, 1.0);
  const PassiveAngleForm form = FitPassiveAngleForm(fitted, 30.0, 100.0);
  EXPECT_LT(form.rms_nm, 0.01);
  EXPECT_NEAR(form.mgl_nm(), leg.mgl, 0.3);
  EXPECT_NEAR(form.hang_deg(), leg.hang, 1.5);
  const PiecewiseLinear extended = ExtendPassiveAngle(fitted, form, 0.0, 120.0);
  EXPECT_DOUBLE_EQ(extended.x().front(), 0.0);
  EXPECT_DOUBLE_EQ(extended.x().back(), 120.0);
  // Inside: the identified curve unchanged.
  for (double th = 30.0; th <= 100.0; th += 5.0) EXPECT_NEAR(extended(th), fitted(th), 1e-9);
  // Outside, down to full extension and up to 110°: within 0.3 N·m of the
  // closed form (a flat hold would be 5.8 N·m off at 10° and 2.6 at 110°).
  for (double th = 10.0; th <= 110.0; th += 2.5) {
    EXPECT_NEAR(extended(th), leg(th), 0.3) << "theta = " << th;
  }
  EXPECT_GT(std::abs(fitted(10.0) - leg(10.0)), 5.0);
}

TEST(Extrapolate, ShortRangeUsesTheAnthropometricGravityMoment) {
  // Pure gravity seen over 76–90° only (a narrow band, docs/MODEL.md "Extrapolation"): with
  // m·g·l known the phase is found and the extrapolation is the sine.
  Leg leg;
  leg.ke = leg.kf = 0.0;
  const PiecewiseLinear fitted = Tabulate(leg, 76.0, 90.0, 1.0);
  const PassiveAngleForm form = FitPassiveAngleForm(fitted, 76.0, 90.0, leg.mgl);
  EXPECT_NEAR(form.mgl_nm(), leg.mgl, 1e-9);
  EXPECT_NEAR(form.hang_deg(), leg.hang, 1.0);
  const PiecewiseLinear extended = ExtendPassiveAngle(fitted, form, 0.0, 120.0);
  for (double th = 10.0; th <= 110.0; th += 5.0) {
    EXPECT_NEAR(extended(th), leg(th), 0.25) << "theta = " << th;
  }
}

TEST(Extrapolate, RejectsEmptyOrTooShortRanges) {
  EXPECT_THROW(FitPassiveAngleForm(PiecewiseLinear(), 10.0, 100.0), std::invalid_argument);
  EXPECT_THROW(FitPassiveAngleForm(PiecewiseLinear::Constant(1.0), 50.0, 53.0),
               std::invalid_argument);
}

TEST(Extrapolate, ActiveAngleFollowsTheGaussianAndNeverRises) {
  // A Gaussian peaking at 60° (σ = 30°) identified over 40–95°.
  const auto g = [](double th) { return std::exp(-(th - 60.0) * (th - 60.0) / (2.0 * 900.0)); };
  const PiecewiseLinear fitted = Tabulate(g, 40.0, 95.0, 5.0);
  const PiecewiseLinear ext = ExtendActiveAngle(fitted, 40.0, 95.0, 0.0, 120.0);
  // Above 95° the Gaussian falls: followed within 0.02.
  for (double th = 100.0; th <= 120.0; th += 5.0) EXPECT_NEAR(ext(th), g(th), 0.02) << th;
  // Below 40° the Gaussian would fall too (past its peak at 60°): followed,
  // and never above the edge value.
  for (double th = 0.0; th < 40.0; th += 5.0) {
    EXPECT_LE(ext(th), fitted(40.0) + 1e-12);
    EXPECT_GE(ext(th), 0.0);
    EXPECT_NEAR(ext(th), g(th), 0.03) << th;
  }
  // Data rising toward an edge (peak beyond it): held there, not rising;
  // on the falling side (ln of a line is concave) below the edge value.
  const auto rising = [](double th) { return 0.2 + 0.01 * th; };
  const PiecewiseLinear r = Tabulate(rising, 30.0, 90.0, 10.0);
  const PiecewiseLinear rext = ExtendActiveAngle(r, 30.0, 90.0, 0.0, 120.0);
  EXPECT_DOUBLE_EQ(rext(120.0), rising(90.0));
  EXPECT_LE(rext(0.0), rising(30.0));
  EXPECT_GE(rext(0.0), 0.0);
}

TEST(Extrapolate, VelocityCurvesContinueTheirEdgeSlopes) {
  // τ_ptv = 0.02·θ̇ identified over −100…150 deg/s: continued to ±1000.
  const PiecewiseLinear ptv({-100.0, 0.0, 150.0}, {-2.0, 0.0, 3.0});
  const PiecewiseLinear p = ExtendVelocityCurve(ptv, -100.0, 150.0, -1000.0, 1000.0, true);
  EXPECT_NEAR(p(-1000.0), -20.0, 1e-9);
  EXPECT_NEAR(p(600.0), 12.0, 1e-9);
  // A negative (non-viscous) edge slope is held.
  const PiecewiseLinear odd({-100.0, 0.0, 150.0}, {1.0, 0.0, -1.0});
  EXPECT_DOUBLE_EQ(ExtendVelocityCurve(odd, -100.0, 150.0, -1000.0, 1000.0, true)(900.0), -1.0);
  // f_atv: concentric side falls to 0 at most, eccentric side never rises.
  const PiecewiseLinear atv({-200.0, 0.0, 200.0}, {0.6, 1.0, 1.3});
  const PiecewiseLinear a = ExtendVelocityCurve(atv, -200.0, 200.0, -1000.0, 1000.0, false);
  EXPECT_NEAR(a(-500.0), 0.0, 1e-9);  // 0.6 − 0.002·800 < 0 → 0
  EXPECT_NEAR(a(-400.0), 0.2, 1e-9);
  EXPECT_DOUBLE_EQ(a(1000.0), 1.3);
}

TEST(Extrapolate, ShareOutsideIdentifiedRanges) {
  Provenance p;
  EXPECT_FALSE(ShareOutsideIdentifiedRanges(p, std::vector<double>{50.0}, {}).has_value());
  p.identified_range_deg = {{"tau_pta", {20.0, 100.0}}, {"f_ata", {30.0, 90.0}}};
  p.identified_range_deg_s = {{"tau_ptv", {-100.0, 100.0}}, {"f_atv", {-50.0, 80.0}}};
  const std::vector<double> angle = {10.0, 25.0, 50.0, 60.0, 95.0, 50.0, 50.0, 50.0};
  const std::vector<double> vel = {0.0, 0.0, 0.0, 90.0, 0.0, -60.0, 10.0, 79.0};
  // Outside: 10° (both), 25° (f_ata), 60° at 90 deg/s (f_atv), 95° (f_ata),
  // −60 deg/s (f_atv): 5 of 8.
  EXPECT_DOUBLE_EQ(*ShareOutsideIdentifiedRanges(p, angle, vel), 5.0 / 8.0);
  // Angles only: 10°, 25°, 95°.
  EXPECT_DOUBLE_EQ(*ShareOutsideIdentifiedRanges(p, angle, {}), 3.0 / 8.0);
  EXPECT_THROW(ShareOutsideIdentifiedRanges(p, angle, std::vector<double>{1.0}),
               std::invalid_argument);
  EXPECT_FALSE(ShareOutsideIdentifiedRanges(p, {}, {}).has_value());
}

}  // namespace
}  // namespace fesbench::model
