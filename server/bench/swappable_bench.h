#pragma once

/// @file
/// The simulated bench behind the RunService, with a virtual subject an
/// admin may replace between runs (BenchService, docs/ARCHITECTURE.md).

#include <memory>
#include <mutex>
#include <vector>

#include "api/status.h"
#include "server/bench/bench.h"
#include "server/bench/simulated_bench.h"
#include "server/bench/virtual_subject.h"

namespace fesbench::server {

/// A Bench that forwards to a SimulatedBench whose virtual subject can be
/// replaced (a new SimulatedBench with the same options is built). Give it to
/// the RunService as its bench and to the BenchService to replace the
/// subject; BenchService does so only while no run holds the bench.
/// Hardware e-stop calls may come from any thread at any time and never
/// wait for the control loop; a latched hardware e-stop carries over to the
/// new subject's bench. Bench time restarts at 0 with a new subject.
class SwappableSimulatedBench final : public Bench {
 public:
  /// The bench for `subject`, or kInvalidArgument (naming the field) if it
  /// fails ValidateVirtualSubject.
  static api::Result<std::unique_ptr<SwappableSimulatedBench>> Create(
      VirtualSubject subject, SimulatedBenchOptions options = {});

  std::string_view kind() const override { return "sim"; }
  const BenchLimits& limits() const override { return options_.limits; }
  void SetStimAmplitude(double stim_ma) override;
  void TriggerPulse(double stim_ma) override;
  void RestartPulseClock() override;
  std::vector<model::Pulse> DrainDeliveredPulses() override;
  void SetMotorMode(MotorMode mode) override;
  void SetMotorSetpoint(double angle_deg) override;
  double Now_s() const override;
  void AdvanceTo(double t_s) override;
  SensorFrame ReadSensors() override;
  std::vector<double> DrainEmg_mv() override;
  void HardwareEStop() override;
  void ClearHardwareEStop() override;
  bool HardwareEStopped() const override;

  /// The current virtual subject (a copy).
  VirtualSubject subject() const;
  double time_scale() const { return options_.time_scale; }
  /// Replaces the virtual subject. Only while no run uses the bench (the
  /// caller's duty: BenchService goes through RunService::WithIdleBench).
  /// kInvalidArgument naming the field for an invalid subject.
  api::Status ReplaceSubject(VirtualSubject subject);
  /// The current SimulatedBench (for tests: truth, delivered pulses).
  std::shared_ptr<SimulatedBench> current() const;

 private:
  SwappableSimulatedBench(SimulatedBenchOptions options, std::shared_ptr<SimulatedBench> bench);

  SimulatedBenchOptions options_;
  mutable std::mutex mu_;  // guards bench_ (the pointer, not the bench)
  std::shared_ptr<SimulatedBench> bench_;
};

}  // namespace fesbench::server
