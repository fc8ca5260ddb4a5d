#include "model/signal.h"

#include <cmath>
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

TEST(PulsesFromEnvelope, BurstsFireOnOneContinuousGridFromTrialStart) {
  // 1 s burst at 20 mA from t = 0.5 s, then a 0.5 s burst at 30 mA from 2 s.
  SampledSignal env{200.0, 0.0, std::vector<double>(600, 0.0)};
  for (int i = 100; i < 300; ++i) env.values[i] = 20.0;
  for (int i = 400; i < 500; ++i) env.values[i] = 30.0;
  const PulseTrain p = PulsesFromEnvelope(env, 33.0);
  // Grid k/33 in [0.5, 1.5): k = 17…49; in [2, 2.5): k = 66…82.
  ASSERT_EQ(p.size(), 33u + 17u);
  EXPECT_DOUBLE_EQ(p[0].t_s, 17.0 / 33.0);  // not at the onset: the grid goes on
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double k = p[i].t_s * 33.0;
    EXPECT_NEAR(k, std::round(k), 1e-9) << "pulse " << i << " off the grid";
  }
  EXPECT_DOUBLE_EQ(p[32].stim_ma, 20.0);
  EXPECT_DOUBLE_EQ(p[33].t_s, 2.0);  // 66/33: the grid, not a restart at the onset
  EXPECT_DOUBLE_EQ(p[33].stim_ma, 30.0);
  // The same bursts shifted by 10 ms fall on the same grid times.
  SampledSignal later{200.0, 0.0, std::vector<double>(600, 0.0)};
  for (int i = 102; i < 302; ++i) later.values[i] = 20.0;
  const PulseTrain q = PulsesFromEnvelope(later, 33.0);
  ASSERT_FALSE(q.empty());
  EXPECT_DOUBLE_EQ(q.front().t_s, 17.0 / 33.0);
}

TEST(PulsesFromEnvelope, EachGridPulseTakesTheEnvelopeHeldAtItsTime) {
  SampledSignal ramp{200.0, 0.0, {}};
  for (int i = 0; i < 200; ++i) ramp.values.push_back(1.0 + i);  // 1 mA per sample
  const PulseTrain p = PulsesFromEnvelope(ramp, 33.0);
  ASSERT_EQ(p.size(), 33u);
  for (std::size_t k = 0; k < p.size(); ++k) {
    EXPECT_DOUBLE_EQ(p[k].t_s, static_cast<double>(k) / 33.0);
    EXPECT_DOUBLE_EQ(p[k].stim_ma, ramp.HoldAt(p[k].t_s)) << k;
  }
}

TEST(PulsesFromEnvelope, ShortRunsAreOneSinglePulseAtTheirStart) {
  SampledSignal env{200.0, 0.0, std::vector<double>(1200, 0.0)};
  env.values[50] = 40.0;    // 0.25 s: between grid times 8/33 and 9/33
  env.values[800] = 45.0;   // 4 s = 132/33: on the grid
  env.values[1000] = 30.0;  // 5 s = 165/33, two samples long
  env.values[1001] = 31.0;
  const PulseTrain p = PulsesFromEnvelope(env, 33.0);
  ASSERT_EQ(p.size(), 3u);
  EXPECT_EQ(p[0], (Pulse{0.25, 40.0}));
  EXPECT_EQ(p[1], (Pulse{4.0, 45.0}));
  EXPECT_EQ(p[2], (Pulse{5.0, 30.0}));
  // Two samples with a grid time inside the second: that grid pulse only.
  SampledSignal two{200.0, 0.0, std::vector<double>(20, 0.0)};
  two.values[5] = two.values[6] = 10.0;  // [25, 35) ms holds 1/33 s
  const PulseTrain q = PulsesFromEnvelope(two, 33.0);
  ASSERT_EQ(q.size(), 1u);
  EXPECT_DOUBLE_EQ(q[0].t_s, 1.0 / 33.0);
}

TEST(PulseClock, GridTimesAndSearch) {
  const PulseClock clock(33.0, 10.0);
  EXPECT_DOUBLE_EQ(clock.TimeOf(0), 10.0);
  EXPECT_DOUBLE_EQ(clock.TimeOf(33), 11.0);
  EXPECT_EQ(clock.FirstAtOrAfter(0.0), 0);
  EXPECT_EQ(clock.FirstAtOrAfter(10.0), 0);
  EXPECT_EQ(clock.FirstAtOrAfter(11.0), 33);
  EXPECT_EQ(clock.FirstAtOrAfter(11.0 - 1e-12), 33);  // round-off is the same instant
  EXPECT_EQ(clock.FirstAtOrAfter(11.0 + 1e-6), 34);
  ASSERT_TRUE(FirstGridTimeIn(0.25, 0.26, 33.0) == std::nullopt);
  ASSERT_TRUE(FirstGridTimeIn(0.25, 0.28, 33.0).has_value());
  EXPECT_DOUBLE_EQ(*FirstGridTimeIn(0.25, 0.28, 33.0), 9.0 / 33.0);
  EXPECT_THROW(PulseClock(0.0), std::invalid_argument);
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
