#include "server/bench/replay_bench.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <thread>

#include "tests/support/manual_clock.h"

namespace fesbench::server {
namespace {

// A 1 s trial at 200 Hz whose channels encode the sample index i:
// angle = base + i, torque = −i/10, accel = i/100, stim = i ≥ 100 ? 30 : 0;
// EMG at 1 kHz = base + k/1000 (k the EMG sample index).
api::Trial MakeTrial(double base, double t0 = 0.0) {
  api::Trial trial;
  std::vector<double> t, angle, torque, accel, stim;
  for (int i = 0; i < 200; ++i) {
    t.push_back(t0 + i / 200.0);
    angle.push_back(base + i);
    torque.push_back(-i / 10.0);
    accel.push_back(i / 100.0);
    stim.push_back(i >= 100 ? 30.0 : 0.0);
  }
  trial.SetChannel("t_s", t);
  trial.SetChannel("angle_deg", angle);
  trial.SetChannel("torque_nm", torque);
  trial.SetChannel("accel_m_s2", accel);
  trial.SetChannel("stim_ma", stim);
  api::ChannelGroup emg;
  emg.sample_rate_hz = 1000.0;
  std::vector<double> te, ve;
  for (int k = 0; k < 1000; ++k) {
    te.push_back(t0 + k / 1000.0);
    ve.push_back(base + k / 1000.0);
  }
  emg.Set("t_s", te);
  emg.Set("emg_mv", ve);
  trial.emg = emg;
  return trial;
}

TEST(ReplayBench, PlaysTrialsBackToBackWithSampleAndHold) {
  auto r = ReplayBench::Create({MakeTrial(10.0), MakeTrial(50.0, 7.0)});
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ReplayBench& bench = **r;
  EXPECT_EQ(bench.kind(), "replay");
  EXPECT_DOUBLE_EQ(bench.TrialStart_s(1), 1.0);
  EXPECT_DOUBLE_EQ(bench.duration_s(), 2.0);

  SensorFrame f = bench.ReadSensors();
  EXPECT_EQ(f.angle_deg, 10.0);
  bench.AdvanceTo(0.503);  // latest sample at or before: i = 100
  f = bench.ReadSensors();
  EXPECT_DOUBLE_EQ(f.t_s, 0.503);
  EXPECT_EQ(f.angle_deg, 110.0);
  EXPECT_DOUBLE_EQ(f.torque_nm, -10.0);
  EXPECT_DOUBLE_EQ(f.accel_m_s2, 1.0);
  EXPECT_EQ(f.stim_ma, 30.0);
  EXPECT_EQ(bench.CurrentTrial(), 0u);

  bench.AdvanceTo(1.2);  // second trial (recorded at t = 7 s), i = 40
  EXPECT_EQ(bench.CurrentTrial(), 1u);
  EXPECT_EQ(bench.ReadSensors().angle_deg, 90.0);
  bench.AdvanceTo(5.0);  // after the end: the last sample
  EXPECT_EQ(bench.ReadSensors().angle_deg, 249.0);
  EXPECT_TRUE(bench.ReadSensors().limit_flexion);
}

TEST(ReplayBench, DrainsEmgByTime) {
  auto r = ReplayBench::Create({MakeTrial(0.0), MakeTrial(5.0)});
  ASSERT_TRUE(r.ok());
  ReplayBench& bench = **r;
  bench.AdvanceTo(0.1);
  std::vector<double> emg = bench.DrainEmg_mv();
  ASSERT_EQ(emg.size(), 101u);  // samples at 0, 1, …, 100 ms
  EXPECT_DOUBLE_EQ(emg.back(), 0.1);
  emg = bench.DrainEmg_mv();
  EXPECT_TRUE(emg.empty());
  bench.AdvanceTo(1.0005);
  emg = bench.DrainEmg_mv();
  ASSERT_EQ(emg.size(), 900u);  // 101 … 999 ms, then the second trial's first
  EXPECT_DOUBLE_EQ(emg.back(), 5.0);
}

TEST(ReplayBench, RecordsCommandsAndHonoursEStop) {
  auto r = ReplayBench::Create({MakeTrial(10.0)});
  ASSERT_TRUE(r.ok());
  ReplayBench& bench = **r;
  bench.AdvanceTo(0.6);
  bench.SetStimAmplitude(25.0);
  bench.SetMotorMode(MotorMode::kLocked);
  bench.SetMotorSetpoint(90.0);
  bench.TriggerPulse(40.0);
  EXPECT_EQ(bench.ReadSensors().stim_ma, 30.0);  // commands change nothing recorded
  std::thread([&] { bench.HardwareEStop(); }).join();
  EXPECT_TRUE(bench.HardwareEStopped());
  const SensorFrame f = bench.ReadSensors();
  EXPECT_TRUE(f.estop);
  EXPECT_EQ(f.stim_ma, 0.0);
  EXPECT_EQ(f.angle_deg, 130.0);
  bench.ClearHardwareEStop();
  EXPECT_EQ(bench.ReadSensors().stim_ma, 30.0);
  const auto cmds = bench.Commands();
  ASSERT_EQ(cmds.size(), 6u);
  EXPECT_EQ(cmds[0].kind, ReplayCommand::Kind::kStimAmplitude);
  EXPECT_DOUBLE_EQ(cmds[0].t_s, 0.6);
  EXPECT_EQ(cmds[0].value, 25.0);
  EXPECT_EQ(cmds[1].value, static_cast<double>(MotorMode::kLocked));
  EXPECT_EQ(cmds[2].value, 90.0);
  EXPECT_EQ(cmds[3].kind, ReplayCommand::Kind::kTriggerPulse);
  EXPECT_EQ(cmds[4].kind, ReplayCommand::Kind::kEStop);
  EXPECT_EQ(cmds[5].kind, ReplayCommand::Kind::kClearEStop);
}

TEST(ReplayBench, PacesWithTheInjectedClock) {
  ::fesbench::testing::ManualClock clock;  // sleeping advances it
  ReplayBenchOptions o;
  o.time_scale = 1.0;
  o.clock = &clock;
  auto r = ReplayBench::Create({MakeTrial(0.0)}, o);
  ASSERT_TRUE(r.ok());
  (*r)->AdvanceTo(0.5);
  EXPECT_NEAR(clock.MonotonicSeconds(), 0.499, 1e-9);
}

TEST(ReplayBench, RejectsBadInput) {
  EXPECT_FALSE(ReplayBench::Create({}).ok());
  api::Trial bad = MakeTrial(0.0);
  bad.FindChannel("t_s")->values[3] = 0.0;  // not increasing
  const auto r = ReplayBench::Create({MakeTrial(0.0), bad});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().field().rfind("trials[1]", 0), 0u) << r.status().ToString();
}

TEST(ReplayBench, ReadsCsvFiles) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("fesbench_replay_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  api::Trial t = MakeTrial(20.0);
  t.emg.reset();
  ASSERT_TRUE(api::WriteTextFile(dir / "a.csv", api::TrialToCsv(t)).ok());
  auto r = ReplayBench::FromCsvFiles({dir / "a.csv"});
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  (*r)->AdvanceTo(0.25);
  EXPECT_EQ((*r)->ReadSensors().angle_deg, 70.0);
  EXPECT_FALSE(ReplayBench::FromCsvFiles({dir / "missing.csv"}).ok());
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace fesbench::server
