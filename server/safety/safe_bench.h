#pragma once

/// @file
/// Safety interlocks (docs/SAFETY.md), the only way anything above reaches a
/// Bench. They hold whatever a client, a protocol or a bug asks for:
/// - stimulation never exceeds the session's max tolerated amplitude nor the
///   bench limit (each clamp is reported as a SafetyEvent);
/// - motor set-points stay inside the subject's range of motion and the
///   bench's mechanical range;
/// - e-stop zeroes stimulation and disables the motor at once, from any
///   thread, and latches until cleared;
/// - a controlling client whose heartbeat stops for longer than the timeout
///   trips the watchdog (heartbeat_watchdog.h), which stops stimulation and the motor like an
///   e-stop (without latching the hardware);
/// - the stimulator's read-back (Bench::DrainDeliveredPulses) is checked
///   after every AdvanceTo: a delivered pulse above the stimulation ceiling —
///   a fault below this layer, a stimulator or a caller of the Bench itself —
///   latches the e-stop at once (within the control period that delivered it).

#include <atomic>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "api/clock.h"
#include "api/run.h"
#include "api/status.h"
#include "server/bench/bench.h"
#include "server/safety/heartbeat_watchdog.h"

namespace fesbench::server {

/// Per-session limits. The effective limits are the intersection with the
/// bench's own (BenchLimits).
struct SafetyLimits {
  double max_stim_ma = 0.0;     ///< subject's recorded max tolerated amplitude.
  double min_angle_deg = 10.0;  ///< subject's range of motion.
  double max_angle_deg = 110.0;
  double heartbeat_timeout_s = 1.0;  ///< watchdog period of the controlling client.
};

/// What the safety layer did (api/run.h: the wire form is one with the events).
using SafetyEvent = api::SafetyEvent;

class SafeBench {
 public:
  using EventSink = std::function<void(const SafetyEvent&)>;

  /// @param bench the hardware; must outlive this object.
  /// @param sink receives every safety event (may be called from any thread
  ///   that triggers an e-stop). May be empty.
  /// @param clock the heartbeat watchdog's (monotonic seconds): client
  ///   liveness is a wall-clock matter even when the simulated bench runs
  ///   faster than real time. Must outlive this object.
  SafeBench(Bench& bench, EventSink sink, api::Clock* clock = api::Clock::Real());

  /// Sets the session's limits; until called, stimulation is limited to 0 mA.
  void Configure(const SafetyLimits& limits);
  SafetyLimits limits() const;

  void SetStimAmplitude(double stim_ma);
  void TriggerPulse(double stim_ma);
  void SetMotorMode(MotorMode mode);
  void SetMotorSetpoint(double angle_deg);

  /// Restarts the stimulator's pulse clock now (Bench::RestartPulseClock).
  void RestartPulseClock() { bench_.RestartPulseClock(); }
  /// The pulses the stimulator delivered (read back and checked by
  /// AdvanceTo) since the previous call, in bench time. Holds at most the
  /// last 100,000 pulses between calls. Thread-safe.
  std::vector<model::Pulse> DrainDeliveredPulses();

  double Now_s() const { return bench_.Now_s(); }
  /// Advances the bench, then reads the stimulator back and e-stops on a
  /// pulse above the ceiling (see the file comment).
  void AdvanceTo(double t_s);
  SensorFrame ReadSensors() { return bench_.ReadSensors(); }

  /// Thread-safe, never blocks on the control loop: cuts stimulation and
  /// motor power through the hardware e-stop and latches.
  void EStop(const std::string& source);
  /// Clears a latched e-stop; the motor stays disabled and stimulation at 0
  /// until commanded again.
  void ClearEStop(const std::string& source);
  bool estopped() const;

  /// Records a heartbeat of the controlling client (wall-clock now).
  void Heartbeat() { watchdog_.Beat(); }
  /// Starts watching heartbeats (a run begins); Disarm stops watching.
  void ArmWatchdog() { watchdog_.Arm(); }
  void DisarmWatchdog() { watchdog_.Disarm(); }
  /// True once the watchdog has fired since it was last armed.
  bool watchdog_fired() const { return watchdog_.fired(); }

  /// What the layer above may read of the bench below. There is no way to
  /// the raw Bench through this class: every command goes through the
  /// interlocks above, and these only read or drain what the bench recorded.
  const BenchLimits& bench_limits() const { return bench_.limits(); }
  /// The hardware stimulator behind the bench (Bench::HardwareStimulator).
  std::optional<Bench::StimulatorInfo> HardwareStimulator() const {
    return bench_.HardwareStimulator();
  }
  /// Why the bench latched its e-stop on its own; OK if it did not
  /// (Bench::HardwareFault).
  api::Status HardwareFault() const { return bench_.HardwareFault(); }
  /// EMG samples (mV) recorded since the previous call (Bench::DrainEmg_mv).
  std::vector<double> DrainEmg_mv() { return bench_.DrainEmg_mv(); }
  /// The commands written to a hardware stimulator since the previous call
  /// (Bench::DrainDeviceCommands). Control thread.
  std::vector<Bench::DeviceCommand> DrainDeviceCommands() { return bench_.DrainDeviceCommands(); }

 private:
  void Emit(SafetyEvent event) const;
  /// min(session max, bench max), 0 when unconfigured or non-finite.
  double StimCeiling() const;
  /// The subject's range of motion intersected with the bench's, never empty.
  std::pair<double, double> AngleRange() const;
  void CheckWatchdog();
  void MakeSafe();
  /// Reads the stimulator back into readback_ and checks every pulse.
  void CheckReadBack();

  Bench& bench_;
  EventSink sink_;
  HeartbeatWatchdog watchdog_;
  mutable std::mutex mu_;  // guards limits_
  SafetyLimits limits_;
  bool configured_ = false;
  std::atomic<bool> estop_{false};
  std::mutex readback_mu_;  // guards readback_
  std::vector<model::Pulse> readback_;
};

}  // namespace fesbench::server
