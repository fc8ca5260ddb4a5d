#include "server/safety/safe_bench.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <thread>
#include <vector>

#include "tests/support/manual_clock.h"

namespace fesbench::server {
namespace {

// Records what reaches the hardware; no physics.
class RecordingBench final : public Bench {
 public:
  std::string_view kind() const override { return "recording"; }
  const BenchLimits& limits() const override { return limits_; }
  void SetStimAmplitude(double stim_ma) override {
    stim_ma_ = hw_estop_ ? 0.0 : stim_ma;
    stim_history_.push_back(stim_ma);
  }
  void TriggerPulse(double stim_ma) override {
    pulses_.push_back(stim_ma);
    // The output stage delivers fault_gain times the command (1 = healthy).
    if (!hw_estop_) delivered_.push_back({t_s_, fault_gain * stim_ma});
  }
  void RestartPulseClock() override { ++clock_restarts_; }
  std::vector<model::Pulse> DrainDeliveredPulses() override {
    std::vector<model::Pulse> out;
    out.swap(delivered_);
    return out;
  }
  void SetMotorMode(MotorMode mode) override { mode_ = mode; }
  void SetMotorSetpoint(double angle_deg) override { setpoints_.push_back(angle_deg); }
  double Now_s() const override { return t_s_; }
  void AdvanceTo(double t_s) override { t_s_ = t_s; }
  SensorFrame ReadSensors() override { return {.t_s = t_s_, .stim_ma = stim_ma_}; }
  std::vector<double> DrainEmg_mv() override { return {}; }
  void HardwareEStop() override {
    hw_estop_ = true;
    stim_ma_ = 0.0;
    mode_ = MotorMode::kDisabled;
  }
  void ClearHardwareEStop() override { hw_estop_ = false; }
  bool HardwareEStopped() const override { return hw_estop_; }

  BenchLimits limits_;
  double t_s_ = 0.0;
  double stim_ma_ = 0.0;
  std::atomic<bool> hw_estop_{false};
  MotorMode mode_ = MotorMode::kDisabled;
  std::vector<double> stim_history_, pulses_, setpoints_;
  std::vector<model::Pulse> delivered_;
  double fault_gain = 1.0;
  int clock_restarts_ = 0;
};

struct Fixture {
  RecordingBench hw;
  std::vector<SafetyEvent> events;
  ::fesbench::testing::ManualClock wall;
  SafeBench safe{hw, [this](const SafetyEvent& e) { events.push_back(e); }, &wall};
};

TEST(SafeBench, NoStimulationBeforeConfiguration) {
  Fixture f;
  f.safe.SetStimAmplitude(20.0);
  EXPECT_EQ(f.hw.stim_history_.back(), 0.0);
  ASSERT_EQ(f.events.size(), 1u);
  EXPECT_EQ(f.events[0].kind, SafetyEvent::Kind::kStimClamped);
}

TEST(SafeBench, ClampsStimulationToSessionAndBenchMaximum) {
  Fixture f;
  f.safe.Configure({.max_stim_ma = 45.0});
  f.safe.SetStimAmplitude(30.0);
  EXPECT_EQ(f.hw.stim_history_.back(), 30.0);
  EXPECT_TRUE(f.events.empty());
  f.safe.SetStimAmplitude(80.0);
  EXPECT_EQ(f.hw.stim_history_.back(), 45.0);
  f.safe.SetStimAmplitude(std::numeric_limits<double>::quiet_NaN());
  EXPECT_EQ(f.hw.stim_history_.back(), 0.0);
  f.safe.SetStimAmplitude(-3.0);
  EXPECT_EQ(f.hw.stim_history_.back(), 0.0);
  f.safe.Configure({.max_stim_ma = 500.0});  // a bad session record cannot exceed the bench
  f.safe.TriggerPulse(250.0);
  EXPECT_EQ(f.hw.pulses_.back(), 100.0);
  EXPECT_EQ(f.events.size(), 4u);
}

TEST(SafeBench, ClampsSetpointsToRangeOfMotion) {
  Fixture f;
  f.safe.Configure({.max_stim_ma = 40.0, .min_angle_deg = 25.0, .max_angle_deg = 120.0});
  f.safe.SetMotorSetpoint(5.0);
  EXPECT_EQ(f.hw.setpoints_.back(), 25.0);
  f.safe.SetMotorSetpoint(115.0);
  EXPECT_EQ(f.hw.setpoints_.back(), 110.0);  // bench stop is tighter than the subject
  f.safe.SetMotorSetpoint(60.0);
  EXPECT_EQ(f.hw.setpoints_.back(), 60.0);
  f.safe.SetMotorSetpoint(std::numeric_limits<double>::infinity());
  EXPECT_EQ(f.hw.setpoints_.size(), 3u);  // ignored
}

TEST(SafeBench, NonsenseLimitsFailSafe) {
  Fixture f;
  f.safe.Configure({.max_stim_ma = std::numeric_limits<double>::quiet_NaN(),
                    .min_angle_deg = 130.0,
                    .max_angle_deg = 150.0});
  f.safe.SetStimAmplitude(20.0);
  EXPECT_EQ(f.hw.stim_history_.back(), 0.0);
  f.safe.SetMotorSetpoint(140.0);
  EXPECT_EQ(f.hw.setpoints_.back(), 110.0);  // never outside the bench's range
  f.safe.Configure({.max_stim_ma = 40.0, .min_angle_deg = 80.0, .max_angle_deg = 60.0});
  f.safe.SetMotorSetpoint(20.0);
  EXPECT_EQ(f.hw.setpoints_.back(), 80.0);  // an empty range is a single point
  f.safe.SetMotorSetpoint(100.0);
  EXPECT_EQ(f.hw.setpoints_.back(), 80.0);
}

TEST(SafeBench, EStopLatchesUntilCleared) {
  Fixture f;
  f.safe.Configure({.max_stim_ma = 40.0});
  f.safe.SetMotorMode(MotorMode::kPosition);
  f.safe.SetStimAmplitude(30.0);
  f.safe.EStop("test");
  EXPECT_TRUE(f.hw.HardwareEStopped());
  EXPECT_EQ(f.hw.stim_ma_, 0.0);
  EXPECT_EQ(f.hw.mode_, MotorMode::kDisabled);
  f.safe.SetStimAmplitude(30.0);
  f.safe.SetMotorMode(MotorMode::kPosition);
  EXPECT_EQ(f.hw.stim_history_.back(), 0.0);
  EXPECT_EQ(f.hw.mode_, MotorMode::kDisabled);
  f.safe.ClearEStop("test");
  EXPECT_FALSE(f.safe.estopped());
  EXPECT_EQ(f.hw.stim_ma_, 0.0);  // clearing does not resume anything
  f.safe.SetStimAmplitude(30.0);
  EXPECT_EQ(f.hw.stim_history_.back(), 30.0);
}

TEST(SafeBench, WatchdogStopsARunWhoseClientFellSilent) {
  Fixture f;
  f.safe.Configure({.max_stim_ma = 40.0, .heartbeat_timeout_s = 1.0});
  f.safe.ArmWatchdog();
  f.safe.SetStimAmplitude(30.0);
  f.wall.Set(0.9);
  f.safe.Heartbeat();
  f.wall.Set(1.8);
  f.safe.AdvanceTo(0.01);
  EXPECT_FALSE(f.safe.watchdog_fired());
  f.wall.Set(2.0);
  f.safe.AdvanceTo(0.02);
  EXPECT_TRUE(f.safe.watchdog_fired());
  EXPECT_EQ(f.hw.stim_ma_, 0.0);
  EXPECT_EQ(f.hw.mode_, MotorMode::kDisabled);
  f.safe.SetStimAmplitude(30.0);
  EXPECT_EQ(f.hw.stim_history_.back(), 0.0);
  ASSERT_FALSE(f.events.empty());
  EXPECT_EQ(f.events.back().kind, SafetyEvent::Kind::kWatchdog);
}

TEST(SafeBench, EStopFromAnotherThreadActsImmediately) {
  Fixture f;
  f.safe.Configure({.max_stim_ma = 40.0});
  f.safe.SetStimAmplitude(30.0);
  std::thread t([&] { f.safe.EStop("other thread"); });
  t.join();
  // The hardware was cut by the e-stop call itself, before any control tick.
  EXPECT_EQ(f.hw.stim_ma_, 0.0);
  EXPECT_TRUE(f.hw.HardwareEStopped());
}

TEST(SafeBench, RandomCommandSequencesNeverBreachLimits) {
  std::mt19937_64 rng(20261121);
  std::uniform_real_distribution<double> any(-200.0, 300.0);
  std::uniform_int_distribution<int> op(0, 6);
  for (int trial = 0; trial < 10000; ++trial) {
    Fixture f;
    const double max_ma = std::uniform_real_distribution<double>(0.0, 120.0)(rng);
    const double lo = std::uniform_real_distribution<double>(0.0, 60.0)(rng);
    const double hi = lo + std::uniform_real_distribution<double>(0.0, 80.0)(rng);
    f.safe.Configure({.max_stim_ma = max_ma, .min_angle_deg = lo, .max_angle_deg = hi});
    const double stim_cap = std::min(max_ma, 100.0);
    const double angle_lo = std::max(lo, 10.0);
    const double angle_hi = std::max(angle_lo, std::min(hi, 110.0));
    bool estopped = false;
    for (int k = 0; k < 20; ++k) {
      switch (op(rng)) {
        case 0:
          f.safe.SetStimAmplitude(any(rng));
          break;
        case 1:
          f.safe.TriggerPulse(any(rng));
          break;
        case 2:
          f.safe.SetMotorSetpoint(any(rng));
          break;
        case 3:
          f.safe.SetMotorMode(static_cast<MotorMode>(rng() % 4));
          break;
        case 4:
          f.safe.EStop("random");
          estopped = true;
          break;
        case 5:
          f.safe.AdvanceTo(f.hw.t_s_ + 0.001);
          break;
        case 6:
          if (rng() % 4 == 0) {
            f.safe.ClearEStop("random");
            estopped = false;
          }
          break;
      }
      ASSERT_LE(f.hw.stim_ma_, stim_cap + 1e-12);
      ASSERT_GE(f.hw.stim_ma_, 0.0);
      if (estopped) {
        ASSERT_EQ(f.hw.stim_ma_, 0.0);
        ASSERT_EQ(f.hw.mode_, MotorMode::kDisabled);
      }
    }
    for (double s : f.hw.stim_history_) ASSERT_LE(s, stim_cap + 1e-12);
    for (double p : f.hw.pulses_) ASSERT_LE(p, stim_cap + 1e-12);
    for (double a : f.hw.setpoints_) {
      ASSERT_GE(a, angle_lo - 1e-12);
      ASSERT_LE(a, angle_hi + 1e-12);
    }
  }
}

// --- stimulator read-back (docs/SAFETY.md) ---------------------------------------

TEST(SafeBench, ReadBackShowsTheClampOfAnOverLimitCommand) {
  Fixture f;
  f.safe.Configure({.max_stim_ma = 30.0});
  f.safe.TriggerPulse(80.0);  // a faulty caller of the safety layer
  f.safe.AdvanceTo(0.001);
  const std::vector<model::Pulse> delivered = f.safe.DrainDeliveredPulses();
  ASSERT_EQ(delivered.size(), 1u);
  EXPECT_EQ(delivered[0].stim_ma, 30.0);  // what reached the leg: the clamp
  EXPECT_FALSE(f.safe.estopped());
  EXPECT_TRUE(f.safe.DrainDeliveredPulses().empty());  // drained once
}

TEST(SafeBench, ReadBackAboveTheCeilingLatchesTheEStop) {
  Fixture f;
  f.safe.Configure({.max_stim_ma = 30.0});
  f.hw.fault_gain = 2.0;  // the output stage delivers twice the command
  f.safe.TriggerPulse(20.0);
  EXPECT_FALSE(f.safe.estopped());
  f.safe.AdvanceTo(0.001);  // read back at the end of the control period
  EXPECT_TRUE(f.safe.estopped());
  EXPECT_TRUE(f.hw.hw_estop_.load());
  ASSERT_FALSE(f.events.empty());
  EXPECT_EQ(f.events.back().kind, SafetyEvent::Kind::kEStop);
  EXPECT_NE(f.events.back().detail.find("read-back"), std::string::npos) << f.events.back().detail;
  // The pulse is still reported as delivered: the read-back does not hide it.
  const std::vector<model::Pulse> delivered = f.safe.DrainDeliveredPulses();
  ASSERT_EQ(delivered.size(), 1u);
  EXPECT_EQ(delivered[0].stim_ma, 40.0);
}

TEST(SafeBench, ReadBackCatchesACallerOfTheBenchItself) {
  Fixture f;
  f.safe.Configure({.max_stim_ma = 30.0});
  f.hw.TriggerPulse(80.0);  // below the safety layer: nothing clamps it
  f.safe.AdvanceTo(0.001);
  EXPECT_TRUE(f.safe.estopped());
  f.safe.TriggerPulse(10.0);  // latched: nothing more goes out
  f.safe.AdvanceTo(0.002);
  EXPECT_EQ(f.hw.pulses_.size(), 1u);
}

TEST(SafeBench, RestartPulseClockReachesTheBench) {
  Fixture f;
  f.safe.RestartPulseClock();
  EXPECT_EQ(f.hw.clock_restarts_, 1);
}

}  // namespace
}  // namespace fesbench::server
