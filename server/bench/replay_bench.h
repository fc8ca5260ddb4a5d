#pragma once

/// @file
/// The replay bench (docs/ARCHITECTURE.md, "The benches"): plays recorded trials back through the
/// Bench interface, for re-running protocol and identification code on real
/// data, demos and tests. Commands are recorded (inspectable) but change
/// nothing.
///
/// Trials play back to back on one bench clock: trial i starts when trial
/// i − 1 ends (its last sample time plus one sample period), its own `t_s`
/// shifted to start there. A sensor read returns, per channel, the latest
/// recorded sample at or before the current bench time (what an A/D reading
/// returns), the first sample before it, the last after the end. Channels
/// read by name (bench_channels below); a channel the trial lacks reads 0.
/// EMG comes from the trial's `emg` group (channel `emg_mv`, its own rate),
/// or from a main-group `emg_mv` channel if there is no group.
/// While the hardware e-stop is latched the stim channel reads 0.
/// The stimulator read-back (DrainDeliveredPulses) plays each trial's
/// recorded pulses (api::Trial::pulses) as bench time passes them; a trial
/// without recorded pulses delivers none. Commands deliver nothing.
/// Storage-backed replay: load the trials with the storage repositories and
/// pass them here.

#include <atomic>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string_view>
#include <vector>

#include "api/status.h"
#include "api/trial.h"
#include "server/bench/bench.h"
#include "server/bench/pacer.h"

namespace fesbench::server {

/// Channel names the benches record and replay (docs/ARCHITECTURE.md, units).
namespace bench_channels {
inline constexpr std::string_view kAngle = "angle_deg";
inline constexpr std::string_view kTorque = "torque_nm";
inline constexpr std::string_view kAccel = "accel_m_s2";
inline constexpr std::string_view kStim = "stim_ma";
inline constexpr std::string_view kEmg = "emg_mv";
}  // namespace bench_channels

/// One command the replay bench received.
struct ReplayCommand {
  enum class Kind {
    kStimAmplitude,
    kTriggerPulse,
    kRestartPulseClock,
    kMotorMode,
    kMotorSetpoint,
    kEStop,
    kClearEStop
  };
  Kind kind;
  double t_s;    ///< bench time.
  double value;  ///< mA, deg, or the MotorMode as a number; 0 for e-stop.
};

struct ReplayBenchOptions {
  BenchLimits limits;
  double time_scale = 0.0;  ///< 0 = as fast as possible.
  api::Clock* clock = api::Clock::Real();  ///< paces the replay; outlives the bench.
};

class ReplayBench final : public Bench {
 public:
  /// kInvalidArgument if there are no trials or one fails api::ValidateTrial
  /// (the message names the trial index and field).
  static api::Result<std::unique_ptr<ReplayBench>> Create(std::vector<api::Trial> trials,
                                                          ReplayBenchOptions options = {});
  /// Reads each CSV (api::ReadTrialCsvFile) and plays them in order.
  static api::Result<std::unique_ptr<ReplayBench>> FromCsvFiles(
      const std::vector<std::filesystem::path>& paths, ReplayBenchOptions options = {});

  std::string_view kind() const override { return "replay"; }
  const BenchLimits& limits() const override { return options_.limits; }

  void SetStimAmplitude(double stim_ma) override;
  void TriggerPulse(double stim_ma) override;
  /// Recorded as a command; the recorded pulses keep their own times.
  void RestartPulseClock() override;
  std::vector<model::Pulse> DrainDeliveredPulses() override;
  void SetMotorMode(MotorMode mode) override;
  void SetMotorSetpoint(double angle_deg) override;

  double Now_s() const override { return now_s_.load(std::memory_order_acquire); }
  /// Moves bench time to t_s (paced by the time scale); never backwards.
  void AdvanceTo(double t_s) override;
  SensorFrame ReadSensors() override;
  /// Recorded EMG samples with times in (previous drain, now].
  std::vector<double> DrainEmg_mv() override;

  void HardwareEStop() override;
  void ClearHardwareEStop() override;
  bool HardwareEStopped() const override { return estop_.load(std::memory_order_acquire); }

  /// Bench time at which trial i starts; total playing time.
  double TrialStart_s(std::size_t i) const { return trials_.at(i).start_s; }
  double duration_s() const { return end_s_; }
  /// Index of the trial playing at the current time (the last one after the end).
  std::size_t CurrentTrial() const;
  /// Every command received so far, in order.
  std::vector<ReplayCommand> Commands() const;

 private:
  struct Track {
    std::vector<double> t_s;       // shifted to bench time
    std::vector<double> values;
  };
  struct Playing {
    double start_s = 0.0;
    double end_s = 0.0;
    Track angle, torque, accel, stim, emg;
    std::vector<model::Pulse> pulses;  // bench time
  };
  explicit ReplayBench(ReplayBenchOptions options);
  static double Sample(const Track& track, double t_s);
  void Record(ReplayCommand::Kind kind, double value);

  ReplayBenchOptions options_;
  Pacer pacer_;
  std::vector<Playing> trials_;
  double end_s_ = 0.0;
  mutable std::mutex mu_;
  std::vector<ReplayCommand> commands_;
  std::atomic<double> now_s_{0.0};
  std::atomic<bool> estop_{false};
  double t_ = 0.0;
  double emg_drained_to_s_ = -1e300;
  double pulses_drained_to_s_ = -1e300;
};

}  // namespace fesbench::server
