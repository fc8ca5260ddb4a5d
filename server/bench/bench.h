#pragma once

/// @file
/// The bench hardware abstraction (docs/ARCHITECTURE.md, "The benches"): what a knee bench can do
/// and sense. Three kinds implement it: the simulated bench (a virtual leg),
/// a replay bench that plays recorded trials, and a real-hardware driver.
/// Nothing above this interface knows which one it drives.
///
/// Threading: one thread (the protocol runner's control loop) calls every
/// method, except `HardwareEStop`, which any thread may call at any time
/// and which must act at once (it is the software twin of the red button
/// that cuts stimulator and motor power, §5.1).

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/status.h"
#include "model/signal.h"

namespace fesbench::server {

/// The model gate's default limit on the predicted speed of the knee at a
/// stop of the range of motion, deg/s (BenchLimits::max_stop_impact_deg_s).
inline constexpr double kDefaultBenchMaxStopImpactDegS = 500.0;

/// Fixed properties of a bench (docs/ARCHITECTURE.md, units; thesis §5.1).
struct BenchLimits {
  double max_stim_ma = 100.0;     ///< stimulator hardware range 0–100 mA.
  double pulse_rate_hz = 33.0;    ///< stimulation pulse rate.
  double pulse_width_us = 300.0;  ///< stimulation pulse width.
  double min_angle_deg = 10.0;    ///< mechanical range of motion.
  double max_angle_deg = 110.0;
  /// Model gate (docs/SAFETY.md, "Model gate"): the fastest a predicted knee may reach a
  /// stop of the range of motion, deg/s. The thesis's own prediction inputs
  /// (§5.4.5) take the knee to full extension at up to about 400 deg/s on the
  /// simulated cohort (the amplitudes reach full extension by design,
  /// §5.4.3); a faster arrival is refused.
  double max_stop_impact_deg_s = kDefaultBenchMaxStopImpactDegS;
  double max_motor_torque_nm = 50.0;  ///< servo torque limit at the knee.
  double control_rate_hz = 1000.0;    ///< motor set-point updates.
  double sample_rate_hz = 200.0;      ///< position, torque, acceleration.
  double emg_rate_hz = 1000.0;        ///< EMG sampling.
};

/// How the motor holds the brace.
enum class MotorMode : std::uint8_t {
  kDisabled,   ///< servo unpowered; the brace is still coupled (motor drag).
  kPosition,   ///< servo follows set-points (passive protocols).
  kLocked,     ///< held at a fixed angle (isometric protocols).
  kDecoupled,  ///< coupler open: the leg swings freely (free-swing protocols).
};

/// One reading of the slow sensors, at bench time t_s.
struct SensorFrame {
  double t_s = 0.0;
  double angle_deg = 0.0;        ///< potentiometer.
  double torque_nm = 0.0;        ///< strut strain gauge (brace on shank, + flexion).
  double accel_m_s2 = 0.0;       ///< tangential accelerometer on the calf (includes gravity).
  /// Read-back: amplitude of the last pulse delivered if it came less than
  /// one pulse period ago, else 0.
  double stim_ma = 0.0;
  bool limit_flexion = false;    ///< limit switch near the 110° stop.
  bool limit_extension = false;  ///< limit switch near the 10° stop.
  bool estop = false;            ///< hardware e-stop engaged.
  /// The subject signals "no higher" (Appendix F part II.K: the tolerance
  /// test's amplitude rises until the subject asks to stop): a hand-held
  /// switch where the bench has one. The simulated subject gives it while
  /// the stimulation is at or above its max tolerated amplitude. Only the
  /// tolerance test reads it; the interlocks do not depend on it.
  bool subject_limit = false;
};

class Bench {
 public:
  virtual ~Bench() = default;

  /// "sim", "replay" or a driver's name.
  virtual std::string_view kind() const = 0;
  virtual const BenchLimits& limits() const = 0;

  /// Stimulation envelope (docs/MODEL.md, pulse timing): the stimulator's pulse clock
  /// fires at every grid time t_k = origin + k / pulse_rate_hz (origin: the
  /// last RestartPulseClock) while the amplitude is > 0, each pulse with the
  /// amplitude set at its time. Setting an amplitude fires nothing by itself;
  /// a pulse due at the very instant AdvanceTo stops at fires on the next
  /// AdvanceTo, with the amplitude set in between.
  virtual void SetStimAmplitude(double stim_ma) = 0;
  /// One single pulse now, off the grid (impulse-response protocols,
  /// §4.1.2: a run of the envelope too short to hold a grid time).
  virtual void TriggerPulse(double stim_ma) = 0;
  /// Restarts the pulse clock's grid at the current bench time (the start of
  /// a trial: a ScienceMode stimulator (re)initialising channel-list mode).
  /// The first grid time is now.
  virtual void RestartPulseClock() = 0;
  /// Read-back of the stimulator's output stage: every pulse it delivered
  /// since the previous call (bench time, delivered amplitude), in order —
  /// the simulated stimulator reports what reached the leg; a real driver
  /// reads the measured pulses back from the stimulator. Nothing a caller
  /// commanded appears here unless it was delivered.
  virtual std::vector<model::Pulse> DrainDeliveredPulses() = 0;

  virtual void SetMotorMode(MotorMode mode) = 0;
  /// Position set-point for kPosition and the lock angle for kLocked.
  virtual void SetMotorSetpoint(double angle_deg) = 0;

  /// Current bench time (seconds since the bench started).
  virtual double Now_s() const = 0;
  /// Lets bench time run to t_s: a real bench sleeps; the simulated bench
  /// integrates its physics (paced by its time scale).
  virtual void AdvanceTo(double t_s) = 0;

  virtual SensorFrame ReadSensors() = 0;
  /// EMG samples (mV) recorded since the previous call.
  virtual std::vector<double> DrainEmg_mv() = 0;

  /// Cuts stimulation and motor power immediately and latches until
  /// ClearHardwareEStop. Thread-safe; never blocks.
  virtual void HardwareEStop() = 0;
  virtual void ClearHardwareEStop() = 0;
  virtual bool HardwareEStopped() const = 0;
  /// Why the bench latched its e-stop on its own (a stimulator driver that
  /// lost its device, a garbled reply, a timeout), OK if it did not. Its
  /// message names the device and the reason ("sciencemode2 stimulator
  /// timeout: …"). Thread-safe. SafeBench adopts such a latch as an e-stop
  /// with this message as its source, and the run ends with it.
  virtual api::Status HardwareFault() const { return api::Status::Ok(); }
  /// The session's stimulation ceiling, mA (SafeBench sets it with the
  /// session's limits): a real driver refuses anything above it on its own,
  /// a second line below SafeBench's clamp. Thread-safe.
  virtual void SetStimulationCeiling(double /*max_ma*/) {}

  /// The hardware stimulator behind this bench: its driver, its own pulse
  /// rate (the period it really fires at) and its current step. nullopt for
  /// the simulated stimulator.
  struct StimulatorInfo {
    std::string device;
    double pulse_rate_hz = 0.0;
    double current_step_ma = 0.0;
    /// The device fires its own train on its own clock (ScienceMode2's
    /// channel list); else the host sends every pulse.
    bool paces_own_train = false;
  };
  virtual std::optional<StimulatorInfo> HardwareStimulator() const { return std::nullopt; }
  /// One command written to a hardware stimulator (api::DeviceCommandLog).
  struct DeviceCommand {
    std::chrono::steady_clock::time_point written;  ///< handed to the serial port.
    double requested_ma = 0.0;                      ///< what the caller asked for.
    double commanded_ma = 0.0;                      ///< what the device was told.
    bool single_pulse = false;
  };
  /// The commands written to the stimulator since the previous call, in
  /// order; none without a hardware stimulator. Control thread.
  virtual std::vector<DeviceCommand> DrainDeviceCommands() { return {}; }
};

}  // namespace fesbench::server
