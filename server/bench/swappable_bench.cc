#include "server/bench/swappable_bench.h"

#include <utility>

namespace fesbench::server {

SwappableSimulatedBench::SwappableSimulatedBench(SimulatedBenchOptions options,
                                                 std::shared_ptr<SimulatedBench> bench)
    : options_(std::move(options)), bench_(std::move(bench)) {}

api::Result<std::unique_ptr<SwappableSimulatedBench>> SwappableSimulatedBench::Create(
    VirtualSubject subject, SimulatedBenchOptions options) {
  api::Result<std::unique_ptr<SimulatedBench>> bench =
      SimulatedBench::Create(std::move(subject), options);
  if (!bench.ok()) return bench.status();
  return std::unique_ptr<SwappableSimulatedBench>(
      new SwappableSimulatedBench(std::move(options), std::move(bench).value()));
}

std::shared_ptr<SimulatedBench> SwappableSimulatedBench::current() const {
  std::lock_guard lock(mu_);
  return bench_;
}

void SwappableSimulatedBench::SetStimAmplitude(double stim_ma) {
  current()->SetStimAmplitude(stim_ma);
}
void SwappableSimulatedBench::TriggerPulse(double stim_ma) { current()->TriggerPulse(stim_ma); }
void SwappableSimulatedBench::RestartPulseClock() { current()->RestartPulseClock(); }
std::vector<model::Pulse> SwappableSimulatedBench::DrainDeliveredPulses() {
  return current()->DrainDeliveredPulses();
}
void SwappableSimulatedBench::SetMotorMode(MotorMode mode) { current()->SetMotorMode(mode); }
void SwappableSimulatedBench::SetMotorSetpoint(double angle_deg) {
  current()->SetMotorSetpoint(angle_deg);
}
double SwappableSimulatedBench::Now_s() const { return current()->Now_s(); }
void SwappableSimulatedBench::AdvanceTo(double t_s) { current()->AdvanceTo(t_s); }
SensorFrame SwappableSimulatedBench::ReadSensors() { return current()->ReadSensors(); }
std::vector<double> SwappableSimulatedBench::DrainEmg_mv() { return current()->DrainEmg_mv(); }
void SwappableSimulatedBench::HardwareEStop() { current()->HardwareEStop(); }
void SwappableSimulatedBench::ClearHardwareEStop() { current()->ClearHardwareEStop(); }
bool SwappableSimulatedBench::HardwareEStopped() const { return current()->HardwareEStopped(); }

VirtualSubject SwappableSimulatedBench::subject() const { return current()->subject(); }

api::Status SwappableSimulatedBench::ReplaceSubject(VirtualSubject subject) {
  api::Result<std::unique_ptr<SimulatedBench>> made =
      SimulatedBench::Create(std::move(subject), options_);
  if (!made.ok()) return made.status();
  std::shared_ptr<SimulatedBench> next = std::move(made).value();
  std::shared_ptr<SimulatedBench> old;
  {
    std::lock_guard lock(mu_);
    // An e-stop latched in hardware stays latched on the new bench.
    if (bench_->HardwareEStopped()) next->HardwareEStop();
    old = std::exchange(bench_, std::move(next));
  }
  return api::Status::Ok();  // `old` is released outside the lock
}

}  // namespace fesbench::server
