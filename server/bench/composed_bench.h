#pragma once

/// @file
/// A bench made of parts (README, "A real stimulator"): stimulation goes to a real stimulator
/// (a StimulatorDevice, e.g. a RehaStim2 over ScienceMode2) and the sensors
/// and the motor are another bench's — today the simulated leg or a replay,
/// later a sensor driver. With the simulated leg this is a dry run of the
/// real stimulator: the virtual leg is stimulated with exactly what the
/// device accepted (its 1 mA steps, rounded down), on the leg's pulse clock,
/// so the read-back (DrainDeliveredPulses) and the recorded trials show
/// what the device was told to deliver.
///
/// Safety: SafeBench clamps above this bench; the device driver refuses
/// anything above the device's or the session's limit as a second line. A
/// device fault (lost, garbled reply, timeout, refusal, its own
/// StimulationError) latches this bench's e-stop with the device's reason
/// (HardwareFault), which SafeBench adopts and the runner reports.
/// HardwareEStop sends the device's stop at once from the calling thread.
///
/// Device updates: a device that runs its own pulse train (ScienceMode2) is
/// told only when the commanded amplitude crosses a step of its resolution,
/// and a single off-grid pulse (TriggerPulse: the impulse protocols, the
/// impulses of the ramp protocols) is its single pulse, which stops the
/// train first. A host-paced device (ScienceMode4 low level) is sent every
/// pulse of the leg's pulse clock, grid or single, as the leg receives it
/// (AdvanceTo). Each command waits for its acknowledgement on the control
/// thread, and is logged with the time it was written, what was asked and
/// what the device was told (DrainDeviceCommands, stored with each trial).
/// A device that paces its own train fires it at its own rate
/// (HardwareStimulator().pulse_rate_hz): the body's pulse clock must run at that
/// rate (the server opens it so) for the leg to be stimulated on the
/// device's grid.

#include <atomic>
#include <memory>
#include <mutex>
#include <string>

#include "server/bench/bench.h"
#include "server/bench/stimulator_device.h"

namespace fesbench::server {

class ComposedBench final : public Bench {
 public:
  /// @param body the sensor and motor side; its stimulation input is fed
  ///   what the device accepted. @param stimulator a connected device.
  ComposedBench(std::unique_ptr<Bench> body, std::unique_ptr<StimulatorDevice> stimulator);
  ~ComposedBench() override;

  std::string_view kind() const override { return kind_; }
  const BenchLimits& limits() const override { return limits_; }
  void SetStimAmplitude(double stim_ma) override;
  void TriggerPulse(double stim_ma) override;
  void RestartPulseClock() override { body_->RestartPulseClock(); }
  std::vector<model::Pulse> DrainDeliveredPulses() override;
  void SetMotorMode(MotorMode mode) override { body_->SetMotorMode(mode); }
  void SetMotorSetpoint(double angle_deg) override { body_->SetMotorSetpoint(angle_deg); }
  double Now_s() const override { return body_->Now_s(); }
  void AdvanceTo(double t_s) override;
  SensorFrame ReadSensors() override;
  std::vector<double> DrainEmg_mv() override { return body_->DrainEmg_mv(); }
  void HardwareEStop() override;
  void ClearHardwareEStop() override;
  bool HardwareEStopped() const override;
  api::Status HardwareFault() const override;
  void SetStimulationCeiling(double max_ma) override { stimulator_->SetSessionLimit(max_ma); }
  std::optional<StimulatorInfo> HardwareStimulator() const override;
  std::vector<DeviceCommand> DrainDeviceCommands() override;

  Bench& body() { return *body_; }
  StimulatorDevice& stimulator() { return *stimulator_; }

 private:
  std::unique_ptr<Bench> body_;
  std::unique_ptr<StimulatorDevice> stimulator_;
  std::string kind_;
  BenchLimits limits_;
  std::atomic<double> sent_ma_{0.0};  ///< the last amplitude the device accepted.
  std::mutex paced_mu_;               // guards paced_
  std::vector<model::Pulse> paced_;   ///< host-paced: pulses sent, not yet drained.
  std::atomic<bool> estop_{false};
  // The control thread's log of commands written to the device, and, for a
  // host-paced device, what was asked for the pulses the leg fires next.
  void LogCommand(double requested_ma, double commanded_ma, bool single_pulse);
  std::vector<DeviceCommand> commands_;
  double requested_train_ma_ = 0.0;
  std::optional<std::pair<double, double>> requested_single_;  // (requested, rounded)
};

}  // namespace fesbench::server
