#include "model/series_elastic.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace fesbench::model {
namespace {

// Index of the largest value.
std::size_t ArgMax(const std::vector<double>& v) {
  return static_cast<std::size_t>(std::max_element(v.begin(), v.end()) - v.begin());
}

// A muscle with a steep active torque–velocity curve near 0 deg/s (Hill-like),
// 2nd-order contraction at 11.7 s⁻¹ as in Fig. 6-13.
ParameterSet SteepVelocityMuscle() {
  ParameterSet p = ExampleParameterSet();
  p.contraction = {2, 11.7};
  p.active.torque_scale_nm = 100.0;
  p.active.torque_velocity = PiecewiseLinear({-100, -50, 0, 50, 100}, {0.0, 0.2, 1.0, 1.4, 1.5});
  return p;
}

TEST(SeriesElasticTest, StiffSeriesElementApproachesRigidIsometric) {
  const ParameterSet p = SteepVelocityMuscle();
  const PulseTrain pulses = {{0.1, 40.0}, {0.4, 45.0}, {0.4 + 1 / 33.0, 45.0}};
  SimulationOptions o = DefaultSeriesElasticOptions();
  o.duration_s = 1.0;
  o.output_rate_hz = 1000.0;
  const SimulationResult rigid = SimulateIsometric(p, pulses, 70.0, o);
  const SeriesElasticResult se =
      SimulateSeriesElasticIsometric(p, {1e4, 1e-4, 0.0}, pulses, 70.0, o);
  ASSERT_EQ(se.joint.size(), rigid.size());
  const double peak =
      *std::max_element(rigid.torque_nm.begin(), rigid.torque_nm.end()) - rigid.torque_nm[0];
  double max_diff = 0.0;
  for (std::size_t i = 0; i < rigid.size(); ++i) {
    max_diff = std::max(max_diff, std::abs(se.joint.torque_nm[i] - rigid.torque_nm[i]));
    EXPECT_NEAR(se.joint.activation[i], rigid.activation[i], 1e-12);
  }
  EXPECT_GT(peak, 5.0);
  EXPECT_LT(max_diff, 0.02 * peak);
}

TEST(SeriesElasticTest, StiffSeriesElementApproachesRigidFreeSwing) {
  const ParameterSet p = ExampleParameterSet();
  PulseTrain pulses;
  for (int k = 0; k < 15; ++k) pulses.push_back({0.2 + k / 33.0, 35.0});
  SimulationOptions o = DefaultSeriesElasticOptions();
  o.duration_s = 1.5;
  o.initial_angle_deg = 90.0;
  const SimulationResult rigid = SimulateFreeSwing(p, pulses, o);
  const SeriesElasticResult se = SimulateSeriesElasticFreeSwing(p, {1e4, 1e-4, 0.0}, pulses, o);
  double max_diff = 0.0, travel = 0.0;
  for (std::size_t i = 0; i < rigid.size(); ++i) {
    max_diff = std::max(max_diff, std::abs(se.joint.angle_deg[i] - rigid.angle_deg[i]));
    travel = std::max(travel, std::abs(rigid.angle_deg[i] - 90.0));
  }
  EXPECT_GT(travel, 10.0);
  EXPECT_LT(max_diff, 0.05);
  EXPECT_EQ(se.joint.torque_nm[10], 0.0);
}

TEST(SeriesElasticTest, CompliantSeriesElementDelaysTheTwitchPeak) {
  const ParameterSet p = SteepVelocityMuscle();
  const PulseTrain pulses = {{0.1, 45.0}};
  SimulationOptions o = DefaultSeriesElasticOptions();
  o.duration_s = 0.8;
  o.output_rate_hz = 2000.0;
  const SimulationResult rigid = SimulateIsometric(p, pulses, 70.0, o);
  const SeriesElasticResult stiff =
      SimulateSeriesElasticIsometric(p, {1000.0, 1e-3, 0.0}, pulses, 70.0, o);
  const SeriesElasticResult soft =
      SimulateSeriesElasticIsometric(p, {4.0, 1e-3, 0.0}, pulses, 70.0, o);
  const double t_rigid = rigid.t_s[ArgMax(rigid.torque_nm)];
  const double t_stiff = stiff.joint.t_s[ArgMax(stiff.joint.torque_nm)];
  const double t_soft = soft.joint.t_s[ArgMax(soft.joint.torque_nm)];
  EXPECT_NEAR(t_rigid, 0.1 + 1.0 / 11.7, 1e-3);  // Eq. 4.2
  EXPECT_NEAR(t_stiff, t_rigid, 2e-3);
  EXPECT_GT(t_soft, t_rigid + 0.02);  // §6.4.1: series compliance delays the peak
  // The CE shortens (extends the knee side) while the SE stretches.
  EXPECT_LT(soft.ce_angle_deg[ArgMax(soft.joint.torque_nm)], 70.0 - 0.5);
  // The SE carries the twitch: its torque equals the brace torque minus the passive part.
  const std::size_t i = ArgMax(soft.joint.torque_nm);
  EXPECT_NEAR(soft.joint.torque_nm[i] - soft.joint.torque_nm[0], soft.se_torque_nm[i], 1e-9);
}

TEST(SeriesElasticTest, RejectsBadParameters) {
  const ParameterSet p = ExampleParameterSet();
  SimulationOptions o = DefaultSeriesElasticOptions();
  o.duration_s = 0.1;
  EXPECT_THROW(SimulateSeriesElasticIsometric(p, {0.0, 1e-3, 0.0}, {}, 90.0, o),
               std::invalid_argument);
  EXPECT_THROW(SimulateSeriesElasticIsometric(p, {35.0, -1.0, 0.0}, {}, 90.0, o),
               std::invalid_argument);
  EXPECT_THROW(SimulateSeriesElasticFreeSwing(p, {35.0, 1e-3, -0.1}, {}, o), std::invalid_argument);
  EXPECT_THROW(SimulateSeriesElasticIsometric(p, {35.0, 1e-3, 0.0}, {}, 200.0, o),
               std::invalid_argument);
}

}  // namespace
}  // namespace fesbench::model
