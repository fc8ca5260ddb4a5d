#include "server/bench/sciencemode4_stimulator.h"

#include <algorithm>
#include <cmath>

namespace fesbench::server::sciencemode4 {

namespace {
constexpr int kInterPhaseUs = 100;  // 0 mA between the two phases
}  // namespace

Stimulator::Stimulator(StimulatorConfig config)
    : config_(std::move(config)), session_max_ma_(config_.session_max_ma) {}

Stimulator::~Stimulator() {
  keeper_.Stop();  // no duty runs while the device is stopped below
  std::lock_guard lock(write_mu_);
  if (initialised_.load() && port_.is_open() && !faulted()) {
    (void)port_.Write(BuildLlStop(NextPacketNumber()));
  }
}

void Stimulator::Fault(const std::string& reason) {
  {
    std::lock_guard lock(write_mu_);
    if (!faulted() && port_.is_open()) (void)port_.Write(BuildLlStop(NextPacketNumber()));
    initialised_.store(false);
    amplitude_ma_.store(0.0);
  }
  std::lock_guard lock(fault_mu_);
  if (fault_.empty()) fault_ = reason;
  faulted_.store(true);
}

std::string Stimulator::fault() const {
  std::lock_guard lock(fault_mu_);
  return fault_;
}

void Stimulator::EmergencyStop() {
  std::lock_guard lock(write_mu_);
  estop_.store(true);
  amplitude_ma_.store(0.0);
  if (!faulted() && port_.is_open()) (void)port_.Write(BuildLlStop(NextPacketNumber()));
  initialised_.store(false);
}

bool Stimulator::Send(const std::vector<std::uint8_t>& wire, bool stimulating) {
  if (faulted()) return false;
  std::string why;
  {
    std::lock_guard lock(write_mu_);
    if (stimulating && estop_.load()) return false;
    // Handed to the port now: the device cannot have it earlier.
    const auto handed = std::chrono::steady_clock::now();
    why = port_.Write(wire);
    if (stimulating) last_command_written_ = handed;
  }
  if (!why.empty()) {
    Fault("stimulator lost: " + why);
    return false;
  }
  return true;
}

bool Stimulator::AwaitAck(Command ack, std::vector<std::uint8_t>* data) {
  const auto deadline = std::chrono::steady_clock::now() + config_.reply_timeout;
  while (true) {
    while (const auto frame = reader_.Pop()) {
      const DecodeResult r = DecodePacket(*frame);
      if (!r.packet) {
        Fault("stimulator reply garbled: " + DecodeErrorName(*r.error));
        return false;
      }
      if (r.packet->command != static_cast<std::uint16_t>(ack)) continue;  // e.g. an e-stop's stop ack
      if (r.packet->packet_number != last_sent_number_) continue;
      const std::uint8_t result = r.packet->data.empty() ? 0xFF : r.packet->data[0];
      if (result != 0) {
        Fault("stimulator refused: " + ResultName(result));
        return false;
      }
      if (data != nullptr) *data = r.packet->data;
      return true;
    }
    if (const std::string why = reader_.ReadReply(deadline, config_.reply_timeout); !why.empty()) {
      Fault(why);
      return false;
    }
  }
}

bool Stimulator::InitLowLevel() {
  last_sent_number_ = NextPacketNumber();
  if (!Send(BuildLlInit(last_sent_number_), /*stimulating=*/true)) return false;
  if (!AwaitAck(Command::kLlInitAck)) return false;
  initialised_.store(!estop_.load());
  return true;
}

bool Stimulator::Connect() {
  std::lock_guard io(io_mu_);
  if (config_.channel < 1 || config_.channel > kChannelCount) {
    Fault("channel must be 1–4, got " + std::to_string(config_.channel));
    return false;
  }
  if (config_.pulse_width_us < 1 || config_.pulse_width_us > kMaxPointTimeUs) {
    Fault("pulse width must be 1–4095 µs, got " + std::to_string(config_.pulse_width_us));
    return false;
  }
  if (const std::string why = port_.Open(config_.port_path, ScienceMode4Settings());
      !why.empty()) {
    Fault(why);
    return false;
  }
  if (!InitLowLevel()) return false;
  last_status_ = std::chrono::steady_clock::now();
  keeper_.Start(std::chrono::milliseconds(50), [this] { return Service(); });
  return true;
}

bool Stimulator::CheckLimit(double stim_ma) {
  const double limit = std::min(kMaxCurrentMa, session_max_ma_.load());
  if (!(stim_ma >= 0.0) || stim_ma > limit) {
    Fault("stimulator refused " + std::to_string(stim_ma) + " mA: outside 0–" +
          std::to_string(limit) + " mA");
    return false;
  }
  return true;
}

bool Stimulator::SetAmplitude(double stim_ma) {
  if (faulted()) return false;
  if (estopped()) return stim_ma == 0.0;
  if (!CheckLimit(stim_ma)) return false;
  amplitude_ma_.store(std::floor(stim_ma / kCurrentStepMa + 1e-9) * kCurrentStepMa);
  return true;
}

std::optional<double> Stimulator::SinglePulse(double stim_ma) {
  std::lock_guard io(io_mu_);
  if (faulted() || estopped()) return std::nullopt;
  if (!CheckLimit(stim_ma)) return std::nullopt;
  if (!initialised_.load() && !InitLowLevel()) return std::nullopt;
  const double current = std::floor(stim_ma / kCurrentStepMa + 1e-9) * kCurrentStepMa;
  const Point points[] = {{config_.pulse_width_us, current},
                          {kInterPhaseUs, 0.0},
                          {config_.pulse_width_us, -current}};
  last_sent_number_ = NextPacketNumber();
  if (!Send(BuildLlChannelConfig(last_sent_number_, config_.channel - 1, 0, points),
            /*stimulating=*/true)) {
    return std::nullopt;
  }
  if (!AwaitAck(Command::kLlChannelConfigAck)) return std::nullopt;
  return current;
}

bool Stimulator::Service() {
  std::lock_guard io(io_mu_);
  if (faulted()) return false;
  if (reader_.ReadAvailable() == FrameReader::ReadOutcome::kHungUp) {
    Fault(kStimulatorLost);
    return false;
  }
  while (const auto frame = reader_.Pop()) {
    const DecodeResult r = DecodePacket(*frame);
    if (!r.packet) {
      Fault("stimulator reply garbled: " + DecodeErrorName(*r.error));
      return false;
    }
  }
  if (std::chrono::steady_clock::now() - last_status_ >= config_.status_interval) {
    return CheckStatusLocked();
  }
  return true;
}

bool Stimulator::CheckStatusLocked() {
  const bool was_initialised = initialised_.load();
  last_status_ = std::chrono::steady_clock::now();
  last_sent_number_ = NextPacketNumber();
  if (!Send(BuildGetStimStatus(last_sent_number_), /*stimulating=*/false)) return false;
  std::vector<std::uint8_t> data;
  if (!AwaitAck(Command::kGetStimStatusAck, &data)) return false;
  if (data.size() < 2) {
    Fault("stimulator status garbled: " + std::to_string(data.size()) + " data bytes");
    return false;
  }
  if (estop_.load()) return true;  // an e-stop's Ll_Stop may land at any moment
  const auto expected = [](bool initialised) {
    return static_cast<std::uint8_t>(initialised ? StimStatus::kLlInitialized
                                                 : StimStatus::kUninitialized);
  };
  if (data[1] != expected(was_initialised) && data[1] != expected(initialised_.load())) {
    Fault("stimulator " + StimStatusName(data[1]) + " where the driver set " +
          StimStatusName(expected(was_initialised)) + ": the device reset or stopped on its own");
    return false;
  }
  return true;
}

}  // namespace fesbench::server::sciencemode4
