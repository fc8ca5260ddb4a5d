#pragma once

/// @file
/// The trial a run is recording (docs/MODEL.md; thesis §5.3): per 200 Hz sample the
/// commanded amplitude, angle, offset-corrected torque and acceleration (and
/// the set-point of motor trials, the controller's signals of tracking
/// trials); EMG at the bench's EMG rate; the stimulator's delivered pulses as
/// read back, and a hardware stimulator's commands with their times.
/// Samples go to the observer in batches as they come; Close
/// turns the buffers into a RecordedTrial with its sample rates from the
/// bench's BenchLimits.

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "api/trial.h"
#include "model/tracking.h"
#include "server/protocols/runner.h"
#include "server/safety/safe_bench.h"

namespace fesbench::server::protocols {

class TrialRecorder {
 public:
  /// `observer` may be null; batches carry `batch_samples` samples.
  TrialRecorder(SafeBench& bench, RunObserver* observer, std::size_t batch_samples)
      : bench_(bench), observer_(observer), batch_samples_(batch_samples) {}

  /// Starts recording trial `index` (named `name`) at run tick `start_tick`
  /// and bench time `bench_start_s`: EMG and the pulse clock start over.
  void Open(int index, std::string name, std::int64_t start_tick, double bench_start_s,
            bool record_setpoint);
  bool open() const { return index_ >= 0; }
  int index() const { return index_; }
  std::int64_t start_tick() const { return start_tick_; }

  /// The torque offset of the segment that follows (raw N·m, §5.3).
  void SetOffset(double offset_nm);
  double offset_nm() const { return offset_nm_; }
  /// A tracking trial: the controller's signals are recorded too.
  void MarkClosedLoop() { closed_loop_ = true; }
  bool closed_loop() const { return closed_loop_; }

  /// One sample at trial time `t_s`: `torque_nm` offset-corrected already;
  /// `tracking` null unless closed loop. Also takes the EMG and pulses read
  /// back so far and sends a batch when one is full.
  void Append(double t_s, double stim_ma, double angle_deg, double torque_nm, double accel_m_s2,
              double setpoint_deg, const model::TrackingSample* tracking);

  /// Sends the last batch, reads back the rest, and returns the trial
  /// (complete = the run did not end inside it). The recorder is closed.
  RecordedTrial Close(bool complete);

 private:
  void EmitBatch(bool all);
  void CollectPulses();
  void Reset();

  SafeBench& bench_;
  RunObserver* observer_;
  std::size_t batch_samples_;

  int index_ = -1;
  std::string name_;
  std::int64_t start_tick_ = 0;
  RecordedTrial recorded_;
  std::vector<double> t_s_, stim_ma_, angle_deg_, torque_nm_, accel_m_s2_, setpoint_deg_;
  std::vector<double> emg_mv_;
  api::PulseRecord pulses_;  // trial time
  std::chrono::steady_clock::time_point start_steady_{};  // the trial's t_s = 0
  bool record_setpoint_ = false;
  bool closed_loop_ = false;
  std::vector<double> target_deg_, feedforward_ma_, correction_ma_, tau_scale_nm_;
  double offset_nm_ = 0.0;
  std::size_t batch_begin_ = 0;
};

}  // namespace fesbench::server::protocols
