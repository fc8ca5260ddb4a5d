#include "model/signal.h"

#include <stdexcept>

#include <gtest/gtest.h>

namespace fesbench::model {
namespace {

TEST(PulsesFromEnvelope, SingleSampleGivesOneImpulse) {
  SampledSignal env{200.0, 0.0, std::vector<double>(200, 0.0)};
  env.values[40] = 35.0;  // one 5 ms sample at t = 0.2 s
  const PulseTrain p = PulsesFromEnvelope(env, 33.0);
  ASSERT_EQ(p.size(), 1u);
  EXPECT_DOUBLE_EQ(p[0].t_s, 0.2);
  EXPECT_DOUBLE_EQ(p[0].stim_ma, 35.0);
}

TEST(PulsesFromEnvelope, BurstGivesTrainAtPulseRate) {
  // 1 s burst at 20 mA from t = 0.5 s, then a 0.5 s burst at 30 mA.
  SampledSignal env{200.0, 0.0, std::vector<double>(600, 0.0)};
  for (int i = 100; i < 300; ++i) env.values[i] = 20.0;
  for (int i = 400; i < 500; ++i) env.values[i] = 30.0;
  const PulseTrain p = PulsesFromEnvelope(env, 33.0);
  // ceil(1 s * 33) = 33 pulses, then ceil(0.5 * 33) = 17.
  ASSERT_EQ(p.size(), 33u + 17u);
  EXPECT_DOUBLE_EQ(p[0].t_s, 0.5);
  EXPECT_NEAR(p[1].t_s - p[0].t_s, 1.0 / 33.0, 1e-12);
  EXPECT_DOUBLE_EQ(p[32].stim_ma, 20.0);
  EXPECT_DOUBLE_EQ(p[33].t_s, 2.0);  // the clock restarts at each onset
  EXPECT_DOUBLE_EQ(p[33].stim_ma, 30.0);
}

TEST(PulsesFromEnvelope, RejectsBadInput) {
  SampledSignal env{200.0, 0.0, {1.0, -1.0}};
  EXPECT_THROW(PulsesFromEnvelope(env, 33.0), std::invalid_argument);
  env.values = {1.0};
  EXPECT_THROW(PulsesFromEnvelope(env, 0.0), std::invalid_argument);
}

TEST(SampledSignal, HoldAndInterpolate) {
  const SampledSignal s{10.0, 1.0, {0.0, 2.0, 4.0}};
  EXPECT_DOUBLE_EQ(s.HoldAt(0.5), 0.0);
  EXPECT_DOUBLE_EQ(s.HoldAt(1.15), 2.0);
  EXPECT_DOUBLE_EQ(s.HoldAt(1.3), 0.0);
  EXPECT_DOUBLE_EQ(s.InterpolateAt(1.05), 1.0);
  EXPECT_DOUBLE_EQ(s.InterpolateAt(9.0), 4.0);
  EXPECT_DOUBLE_EQ(s.EndTime(), 1.3);
}

TEST(SampledTrajectory, InterpolatesColumns) {
  const SampledTrajectory tr(100.0, {10, 20}, {1000, 1000}, {0, 50});
  const Kinematics k = tr.At(0.005);
  EXPECT_DOUBLE_EQ(k.angle_deg, 15.0);
  EXPECT_DOUBLE_EQ(k.velocity_deg_s, 1000.0);
  EXPECT_DOUBLE_EQ(k.accel_deg_s2, 25.0);
  EXPECT_DOUBLE_EQ(tr.duration_s(), 0.01);
  EXPECT_THROW(SampledTrajectory(100.0, {1, 2}, {1}, {1, 2}), std::invalid_argument);
}

}  // namespace
}  // namespace fesbench::model
