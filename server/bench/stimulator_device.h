#pragma once

/// @file
/// The stimulator half of a bench made of parts (ComposedBench): a real
/// stimulator behind a driver. The simulated stimulator is part of the
/// simulated leg (SimulatedBench) and needs no device.
///
/// Threading: one control thread calls SetAmplitude, Service and ClearEStop;
/// EmergencyStop, estopped and fault may be called from any thread, and
/// EmergencyStop acts at once without waiting for the device's reply.
///
/// Errors (docs/ARCHITECTURE.md, "Errors"): every command returns an
/// api::Status or api::Result. A fault is kUnavailable (the device lost,
/// garbled, timed out or refused), kFailedPrecondition (an amplitude above
/// a limit) or kInvalidArgument (a configuration the device cannot take),
/// and is the latched fault() itself; kConflict means the command was not
/// sent because an e-stop is latched (not a fault).

#include <chrono>
#include <optional>
#include <string>
#include <string_view>

#include "api/status.h"

namespace fesbench::server {

class StimulatorDevice {
 public:
  virtual ~StimulatorDevice() = default;

  /// The driver's name, e.g. "sciencemode2".
  virtual std::string_view name() const = 0;
  /// The device's own current limit, mA.
  virtual double max_current_ma() const = 0;
  /// The device's current step, mA: a command is delivered rounded down to
  /// it (never above what was commanded).
  virtual double current_step_ma() const = 0;
  /// True if the device fires only the pulses the host sends one by one
  /// (ScienceMode4 low level): the bench then sends every pulse of its own
  /// pulse clock through SinglePulse. False if the device runs the pulse
  /// train itself at its own rate (ScienceMode2 channel-list mode) and
  /// SetAmplitude changes it.
  virtual bool host_paced() const { return false; }

  /// The session's maximum, mA: SetAmplitude refuses (as a fault) anything
  /// above it. Thread-safe.
  virtual void SetSessionLimit(double max_ma) = 0;
  /// Sets the current of every pulse from the device's next pulse on and
  /// waits for the device to accept it. The fault on a fault (the device
  /// has been told to stop), kConflict while e-stopped (nothing is sent; 0 mA
  /// is accepted).
  virtual api::Status SetAmplitude(double stim_ma) = 0;
  /// One pulse now, off the pulse grid (docs/MODEL.md's single pulse), at
  /// stim_ma rounded down to the step; leaves any running pulse train
  /// stopped (the next SetAmplitude starts it again). Returns the amplitude
  /// delivered, or the fault, or kConflict while e-stopped.
  virtual api::Result<double> SinglePulse(double stim_ma) = 0;
  /// The amplitude the device last accepted, mA (0 after a stop).
  virtual double delivered_ma() const = 0;
  /// When the last command that sets stimulation (an amplitude, a single
  /// pulse) was handed to the serial port (just before its write: the device
  /// cannot have read it earlier). Control thread.
  virtual std::chrono::steady_clock::time_point last_command_written() const = 0;
  /// The pulse rate the device really fires its own train at (its period
  /// rounded to the device's resolution), Hz; nullopt for a host-paced
  /// device, whose pulses fire when the host sends them.
  virtual std::optional<double> own_pulse_rate_hz() const { return std::nullopt; }
  /// The device's periodic duties (its watchdog, messages it sends on its
  /// own); call every control period. The fault on a fault.
  virtual api::Status Service() = 0;

  /// Stops stimulation now and latches until ClearEStop.
  virtual void EmergencyStop() = 0;
  /// Ends an EmergencyStop latch (not a fault).
  virtual void ClearEStop() = 0;
  virtual bool estopped() const = 0;
  /// Why the device failed (lost, garbled, timed out, refused); OK if it has
  /// not. A fault stays latched until the device is reconnected.
  virtual api::Status fault() const = 0;
};

}  // namespace fesbench::server
