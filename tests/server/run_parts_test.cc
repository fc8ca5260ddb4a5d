// The parts ProtocolRunner::Run is made of: the tolerance test's
// detector against hand-computed windows, and the trial recorder on the
// simulated bench (channels, offsets, batches, rates from BenchLimits).

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "server/bench/simulated_bench.h"
#include "server/bench/virtual_subject.h"
#include "server/protocols/tolerance_detector.h"
#include "server/protocols/trial_recorder.h"

namespace fesbench::server::protocols {
namespace {

TEST(ToleranceDetector, TheThresholdIsTheFirstTenSampleMeanAboveTheBand) {
  ToleranceSettings settings;
  settings.threshold_torque_nm = 0.5;
  settings.min_torque_at_max_nm = 6.0;
  ToleranceDetector detector(settings);
  detector.SetOffsetNoise(0.05);  // 4σ = 0.2 < 0.5: the setting rules
  EXPECT_DOUBLE_EQ(detector.current().noise_band_nm, 0.5);
  detector.SetOffsetNoise(0.25);  // 4σ = 1.0
  EXPECT_DOUBLE_EQ(detector.current().noise_band_nm, 1.0);
  // Torque 0 for 20 samples, then 2 N·m: the 10-sample mean passes 1.0 at
  // the 6th sample of 2 N·m (mean 1.2; the 5th gives exactly 1.0).
  std::vector<double> applied;
  for (int i = 0; i < 40; ++i) {
    const double u = 10.0 + 0.1 * i;
    applied.push_back(u);
    detector.Sample(i < 20 ? 0.0 : 2.0, u);
  }
  ASSERT_TRUE(detector.current().threshold_ma.has_value());
  EXPECT_DOUBLE_EQ(*detector.current().threshold_ma, applied[25]);
  EXPECT_DOUBLE_EQ(detector.current().max_tolerated_ma, applied.back());
  EXPECT_DOUBLE_EQ(detector.current().max_torque_nm, 2.0);
  const ToleranceResult result = detector.Finish();
  ASSERT_EQ(result.warnings.size(), 1u);  // 2 N·m at the max: below 6
  EXPECT_NE(result.warnings[0].find("6 N·m"), std::string::npos) << result.warnings[0];
}

TEST(ToleranceDetector, NoResponseIsWarnedAndTheStopIsKept) {
  ToleranceSettings settings;
  settings.min_torque_at_max_nm = 3.5;
  ToleranceDetector detector(settings);
  detector.SetOffsetNoise(0.1);
  for (int i = 0; i < 30; ++i) detector.Sample(0.1, 5.0 + i);
  detector.MarkStoppedByClinician();
  const ToleranceResult result = detector.Finish();
  EXPECT_FALSE(result.threshold_ma.has_value());
  EXPECT_TRUE(result.stopped_by_clinician);
  EXPECT_DOUBLE_EQ(result.max_tolerated_ma, 34.0);
  ASSERT_EQ(result.warnings.size(), 2u);
  EXPECT_NE(result.warnings[0].find("3.5 N·m"), std::string::npos) << result.warnings[0];
  EXPECT_EQ(result.warnings[1], "no torque response above the noise band");
}

class CountingObserver : public RunObserver {
 public:
  void OnSamples(const SampleBatch& batch) override {
    batches.push_back(batch.t_s.size());
    samples += batch.t_s.size();
    EXPECT_EQ(batch.trial_name, "active_ramp");
  }
  std::vector<std::size_t> batches;
  std::size_t samples = 0;
};

TEST(TrialRecorder, RecordsChannelsOffsetsAndBatchesAtTheBenchsRates) {
  const std::unique_ptr<SimulatedBench> bench_owner =
      SimulatedBench::Create(DrawVirtualSubject(3)).value();
  SimulatedBench& bench = *bench_owner;
  SafetyEventLog log;
  SafeBench safe(bench, log.sink());
  CountingObserver observer;
  TrialRecorder recorder(safe, &observer, 40);
  EXPECT_FALSE(recorder.open());
  recorder.Open(2, "active_ramp", 1000, 1.0, /*record_setpoint=*/true);
  ASSERT_TRUE(recorder.open());
  EXPECT_EQ(recorder.index(), 2);
  EXPECT_EQ(recorder.start_tick(), 1000);
  recorder.SetOffset(0.25);
  EXPECT_DOUBLE_EQ(recorder.offset_nm(), 0.25);
  constexpr int kSamples = 100;
  for (int i = 0; i < kSamples; ++i) {
    safe.AdvanceTo(1.0 + (i + 1) / 200.0);
    recorder.Append(i / 200.0, 0.0, 60.0 + i, 1.0 - 0.25, 9.81, 45.0, nullptr);
  }
  EXPECT_EQ(observer.batches, (std::vector<std::size_t>{40, 40}));  // the rest comes at Close
  const RecordedTrial trial = recorder.Close(/*complete=*/false);
  EXPECT_FALSE(recorder.open());
  EXPECT_EQ(observer.samples, static_cast<std::size_t>(kSamples));
  EXPECT_FALSE(trial.complete);
  EXPECT_DOUBLE_EQ(trial.bench_start_s, 1.0);
  EXPECT_EQ(trial.offsets_nm, std::vector<double>{0.25});
  EXPECT_EQ(trial.trial.name, "active_ramp");
  EXPECT_DOUBLE_EQ(trial.trial.sample_rate_hz, safe.bench_limits().sample_rate_hz);
  const std::vector<double>* angle = trial.trial.Values("angle_deg");
  ASSERT_NE(angle, nullptr);
  ASSERT_EQ(angle->size(), static_cast<std::size_t>(kSamples));
  EXPECT_DOUBLE_EQ(angle->back(), 60.0 + kSamples - 1);
  EXPECT_DOUBLE_EQ(trial.trial.Values("torque_nm")->front(), 0.75);
  EXPECT_EQ(trial.trial.Values("setpoint_deg")->size(), static_cast<std::size_t>(kSamples));
  EXPECT_EQ(trial.trial.Values("stim_delivered_ma")->size(), static_cast<std::size_t>(kSamples));
  EXPECT_EQ(trial.trial.Values("target_deg"), nullptr);  // not a tracking trial
  // A second trial starts empty.
  recorder.Open(3, "active_ramp", 3000, 2.0, false);
  recorder.Append(0.0, 0.0, 1.0, 0.0, 0.0, 0.0, nullptr);
  const RecordedTrial next = recorder.Close(true);
  EXPECT_EQ(next.trial.Values("angle_deg")->size(), 1u);
  EXPECT_TRUE(next.offsets_nm.empty());
  EXPECT_EQ(next.trial.Values("setpoint_deg"), nullptr);
}

}  // namespace
}  // namespace fesbench::server::protocols
