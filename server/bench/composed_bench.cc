#include "server/bench/composed_bench.h"

#include <algorithm>
#include <cmath>

namespace fesbench::server {

ComposedBench::ComposedBench(std::unique_ptr<Bench> body,
                             std::unique_ptr<StimulatorDevice> stimulator)
    : body_(std::move(body)), stimulator_(std::move(stimulator)) {
  kind_ = std::string(stimulator_->name()) + "+" + std::string(body_->kind());
  limits_ = body_->limits();
  limits_.max_stim_ma = std::min(limits_.max_stim_ma, stimulator_->max_current_ma());
}

ComposedBench::~ComposedBench() { stimulator_->EmergencyStop(); }

void ComposedBench::SetStimAmplitude(double stim_ma) {
  if (HardwareEStopped()) {
    body_->SetStimAmplitude(0.0);
    sent_ma_.store(0.0);  // the device stopped: the next start is sent
    return;
  }
  if (stimulator_->host_paced()) {
    // Nothing to send: the leg's pulse clock paces the device (AdvanceTo).
    requested_train_ma_ = stim_ma;
    if (!stimulator_->SetAmplitude(stim_ma).ok()) {
      if (!stimulator_->estopped()) HardwareEStop();
      body_->SetStimAmplitude(0.0);
      return;
    }
    body_->SetStimAmplitude(stimulator_->delivered_ma());
    return;
  }
  // Only a change of at least one device step is sent (the device keeps
  // delivering the last accepted amplitude at its pulse rate).
  const double step = stimulator_->current_step_ma();
  const double wanted = std::floor(stim_ma / step + 1e-9) * step;
  if (wanted != sent_ma_.load()) {
    if (!stimulator_->SetAmplitude(stim_ma).ok()) {
      if (!stimulator_->estopped()) HardwareEStop();  // a fault: latch with its reason
      body_->SetStimAmplitude(0.0);
      sent_ma_.store(0.0);
      return;
    }
    sent_ma_.store(stimulator_->delivered_ma());
    LogCommand(stim_ma, stimulator_->delivered_ma(), false);
  }
  body_->SetStimAmplitude(sent_ma_.load());
}

void ComposedBench::TriggerPulse(double stim_ma) {
  if (stim_ma <= 0.0 || HardwareEStopped()) return;
  if (stimulator_->host_paced()) {
    // The leg fires it now; AdvanceTo sends it to the device.
    const double step = stimulator_->current_step_ma();
    const double rounded = std::floor(stim_ma / step + 1e-9) * step;
    requested_single_ = std::pair{stim_ma, rounded};
    body_->TriggerPulse(rounded);
    return;
  }
  const api::Result<double> delivered = stimulator_->SinglePulse(stim_ma);
  sent_ma_.store(0.0);  // the device's pulse train is stopped either way
  if (!delivered.ok()) {
    if (!stimulator_->estopped()) HardwareEStop();  // a fault: latch with its reason
    return;
  }
  LogCommand(stim_ma, *delivered, true);
  if (*delivered > 0.0) body_->TriggerPulse(*delivered);
}

void ComposedBench::AdvanceTo(double t_s) {
  body_->AdvanceTo(t_s);
  if (stimulator_->host_paced()) {
    std::vector<model::Pulse> pulses = body_->DrainDeliveredPulses();
    for (const model::Pulse& p : pulses) {
      if (HardwareEStopped()) break;
      const api::Result<double> sent = stimulator_->SinglePulse(p.stim_ma);
      if (!sent.ok()) {
        if (!stimulator_->estopped()) HardwareEStop();  // a fault: latch with its reason
        break;
      }
      // The pulse TriggerPulse asked for, or one of the train's.
      const bool single = requested_single_ && requested_single_->second == p.stim_ma;
      LogCommand(single ? requested_single_->first : std::max(requested_train_ma_, *sent), *sent,
                 single);
      if (single) requested_single_.reset();
    }
    std::lock_guard lock(paced_mu_);
    paced_.insert(paced_.end(), pulses.begin(), pulses.end());
  }
  if (!stimulator_->Service().ok() && !estop_.load()) HardwareEStop();
}

void ComposedBench::LogCommand(double requested_ma, double commanded_ma, bool single_pulse) {
  commands_.push_back(
      {stimulator_->last_command_written(), requested_ma, commanded_ma, single_pulse});
}

std::vector<Bench::DeviceCommand> ComposedBench::DrainDeviceCommands() {
  std::vector<DeviceCommand> out;
  out.swap(commands_);
  return out;
}

std::optional<Bench::StimulatorInfo> ComposedBench::HardwareStimulator() const {
  return StimulatorInfo{std::string(stimulator_->name()),
                        stimulator_->own_pulse_rate_hz().value_or(limits_.pulse_rate_hz),
                        stimulator_->current_step_ma(), !stimulator_->host_paced()};
}

std::vector<model::Pulse> ComposedBench::DrainDeliveredPulses() {
  if (!stimulator_->host_paced()) return body_->DrainDeliveredPulses();
  std::vector<model::Pulse> out;
  std::lock_guard lock(paced_mu_);
  out.swap(paced_);
  return out;
}

SensorFrame ComposedBench::ReadSensors() {
  SensorFrame frame = body_->ReadSensors();
  frame.estop = frame.estop || HardwareEStopped();
  return frame;
}

void ComposedBench::HardwareEStop() {
  stimulator_->EmergencyStop();
  body_->HardwareEStop();
  estop_.store(true);
}

void ComposedBench::ClearHardwareEStop() {
  // A device fault stays latched: the device must be reconnected (a new
  // server).
  if (!stimulator_->fault().ok()) return;
  sent_ma_.store(0.0);
  stimulator_->ClearEStop();
  body_->ClearHardwareEStop();
  estop_.store(false);
}

bool ComposedBench::HardwareEStopped() const {
  return estop_.load() || stimulator_->estopped() || !stimulator_->fault().ok();
}

api::Status ComposedBench::HardwareFault() const {
  const api::Status fault = stimulator_->fault();
  if (fault.ok()) return fault;
  // e.g. "sciencemode2 stimulator timeout: …"
  return {fault.code(), std::string(stimulator_->name()) + " " + fault.message()};
}

}  // namespace fesbench::server
