#include "model/identify_active.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "model/contraction.h"
#include "model/identify_simplified.h"
#include "model/parameter_set.h"
#include "model/simulate.h"
#include "model/stimulus_generators.h"
#include "model/units.h"
#include "tests/model/identify_test_helpers.h"

namespace fesbench::model {
namespace {

TrialColumns FreeSwing(const ParameterSet& p, std::uint64_t seed,
                       std::optional<ModelKind> kind = {}) {
  const SampledSignal env = MakeStimulus(
      "random_binary_dense", {{"amplitude_ma", 26}, {"seed", static_cast<double>(seed)}});
  return test_helpers::SimulatedFreeSwing(p, env, kind);
}

// Range of the samples the active fit uses.
std::pair<double, double> ActiveRange(const TrialColumns& tr, const std::vector<double>& x) {
  double lo = 1e9, hi = -1e9;
  for (std::size_t i = 0; i < tr.size(); ++i) {
    if (tr.activation[i] >= 0.01) lo = std::min(lo, x[i]), hi = std::max(hi, x[i]);
  }
  return {lo, hi};
}

double MaxRelDiff(const PiecewiseLinear& a, const PiecewiseLinear& b, double lo, double hi,
                  double step) {
  double e = 0.0;
  for (double x = lo; x <= hi + 1e-9; x += step) e = std::max(e, std::abs(a(x) / b(x) - 1.0));
  return e;
}

TEST(ActiveTorque, IsMinusThePassiveTorqueInFreeSwing) {
  const ParameterSet p = ExampleParameterSet();
  TrialColumns tr;
  tr.t_s = {0.0, 0.005};
  tr.angle_deg = {60.0, 90.0};
  tr.velocity_deg_s = {10.0, 0.0};
  tr.accel_deg_s2 = {100.0, 0.0};
  const auto t = ActiveTorque(tr, p.passive);
  EXPECT_NEAR(t[0],
              -(p.passive.inertia_kgm2 * DegToRad(100.0) + p.passive.torque_velocity(10.0) +
                p.passive.torque_angle(60.0)),
              1e-12);
  EXPECT_NEAR(t[1], -p.passive.torque_velocity(0.0), 1e-12);
}

TEST(IdentifyActive, LogDomainFitRecoversCurvesWithin2Percent) {
  const ParameterSet p = ExampleParameterSet();
  const std::vector<TrialColumns> trials = {FreeSwing(p, 1), FreeSwing(p, 2)};
  ActiveOptions o;
  o.angle.explicit_x = p.active.torque_angle.x();
  o.velocity.explicit_x = p.active.torque_velocity.x();
  const ActiveResult r = IdentifyActive(trials, p.passive, o);
  EXPECT_NEAR(r.active.torque_angle(90.0), 1.0, 1e-12);  // §6.7 normalisation
  EXPECT_NEAR(r.active.torque_velocity(0.0), 1.0, 1e-12);
  EXPECT_NEAR(r.active.torque_scale_nm, p.active.torque_scale_nm, 0.02 * p.active.torque_scale_nm);
  const auto [a_lo, a_hi] = ActiveRange(trials[0], trials[0].angle_deg);
  const auto [v_lo, v_hi] = ActiveRange(trials[0], trials[0].velocity_deg_s);
  // Interior of the visited range, where breakpoints on both sides are supported.
  const double a0 = std::ceil(a_lo / 10.0) * 10.0, a1 = std::floor(a_hi / 10.0) * 10.0;
  const double v0 = std::ceil(v_lo / 100.0) * 100.0, v1 = std::floor(v_hi / 100.0) * 100.0;
  ASSERT_LT(a0, a1);
  ASSERT_LT(v0, v1);
  EXPECT_LT(MaxRelDiff(r.active.torque_angle, p.active.torque_angle, a0, a1, 1.0), 0.02);
  EXPECT_LT(MaxRelDiff(r.active.torque_velocity, p.active.torque_velocity, v0, v1, 5.0), 0.02);
  EXPECT_LT(r.report.fit_rms.at("active_nm"), 0.05 * p.active.torque_scale_nm);
}

TEST(IdentifyActive, RejectsTrialWithoutActivation) {
  TrialColumns tr = FreeSwing(ExampleParameterSet(), 1);
  tr.activation.clear();
  EXPECT_THROW(IdentifyActive(std::span(&tr, 1), ExampleParameterSet().passive),
               std::invalid_argument);
}

TEST(IdentifySimplified, TorqueGeneratorRecoversScale) {
  ParameterSet p = ExampleParameterSet();
  p.active.torque_scale_nm = 33.0;
  const TrialColumns tr = FreeSwing(p, 3, ModelKind::kTorqueGenerator);
  const SimplifiedResult r = IdentifySimplified(ModelKind::kTorqueGenerator, std::span(&tr, 1), p);
  EXPECT_EQ(r.params.model, ModelKind::kTorqueGenerator);
  EXPECT_NEAR(r.params.active.torque_scale_nm, 33.0, 0.01 * 33.0);
  EXPECT_LT(r.report.fit_rms.at("torque_generator_nm"), 0.1);
}

TEST(IdentifySimplified, SingleSegmentRecoversLines) {
  ParameterSet p = ExampleParameterSet();
  p.single_segment = {-0.004, 1.36, 0.0012, 1.0};  // f_ata(90) = 1
  const TrialColumns tr = FreeSwing(p, 4, ModelKind::kSingleSegment);
  const SimplifiedResult r = IdentifySimplified(ModelKind::kSingleSegment, std::span(&tr, 1), p);
  EXPECT_NEAR(r.params.single_segment.a, -0.004, 2e-4);
  EXPECT_NEAR(r.params.single_segment.b, 1.36, 0.02);
  EXPECT_NEAR(r.params.single_segment.c, 0.0012, 6e-5);
  EXPECT_DOUBLE_EQ(r.params.single_segment.d, 1.0);
  EXPECT_NEAR(r.params.active.torque_scale_nm, 40.0, 0.8);
}

TEST(IdentifySimplified, StaticGainPwlVelocityRecoversCurve) {
  ParameterSet p = ExampleParameterSet();
  const TrialColumns tr = FreeSwing(p, 5, ModelKind::kStaticGainPwlVelocity);
  SimplifiedOptions o;
  o.velocity.explicit_x = p.active.torque_velocity.x();
  const SimplifiedResult r =
      IdentifySimplified(ModelKind::kStaticGainPwlVelocity, std::span(&tr, 1), p, o);
  EXPECT_NEAR(r.params.active.torque_scale_nm, 40.0, 0.02 * 40.0);
  const auto [v_lo, v_hi] = ActiveRange(tr, tr.velocity_deg_s);
  EXPECT_LT(MaxRelDiff(r.params.active.torque_velocity, p.active.torque_velocity,
                       std::ceil(v_lo / 100) * 100, std::floor(v_hi / 100) * 100, 5.0),
            0.02);
}

TEST(IdentifySimplified, ParametricRecoversGaussianAndSlopes) {
  ParameterSet p = ExampleParameterSet();
  p.parametric = {8.0, 0.05, 3.0, -6.0, 65.0, 35.0, 0.0015, 0.0008};
  // The PWL τ_pta the fit uses for τ_act: Eq. 7.3 sampled every degree
  // (over a wide range: this weak gravity-like τ_pta lets the leg swing far).
  std::vector<double> x, y;
  for (double th = -120; th <= 240; th += 1.0) {
    x.push_back(th);
    y.push_back(8.0 * std::sin(DegToRad(th)) + 0.05 * std::exp(3.0 * DegToRad(th)) - 6.0);
  }
  p.passive.torque_angle = PiecewiseLinear(x, y);
  const TrialColumns tr = FreeSwing(p, 6, ModelKind::kParametric);
  const SimplifiedResult r = IdentifySimplified(ModelKind::kParametric, std::span(&tr, 1), p);
  const ParametricParams& q = r.params.parametric;
  EXPECT_NEAR(q.mgl_nm, 8.0, 0.1);
  EXPECT_NEAR(q.k2_per_rad, 3.0, 0.1);
  EXPECT_NEAR(q.offset_nm, -6.0, 0.1);
  EXPECT_NEAR(q.ata_peak_deg, 65.0, 2.0);
  EXPECT_NEAR(q.ata_width_deg, 35.0, 1.5);
  EXPECT_NEAR(q.atv_slope_neg_per_deg_s, 0.0015, 1e-4);
  EXPECT_NEAR(q.atv_slope_pos_per_deg_s, 0.0008, 1e-4);
  EXPECT_NEAR(r.params.active.torque_scale_nm, 40.0, 0.8);
}

}  // namespace
}  // namespace fesbench::model
