#include "server/bench/sciencemode4_stimulator.h"

#include <algorithm>
#include <cmath>
#include <utility>

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

api::Status Stimulator::Fault(api::Status reason) {
  {
    std::lock_guard lock(write_mu_);
    if (!faulted() && port_.is_open()) (void)port_.Write(BuildLlStop(NextPacketNumber()));
    initialised_.store(false);
    amplitude_ma_.store(0.0);
  }
  std::lock_guard lock(fault_mu_);
  if (fault_.ok()) fault_ = std::move(reason);
  faulted_.store(true);
  return fault_;
}

api::Status Stimulator::fault() const {
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

namespace {
// A command not sent because an e-stop is latched: not a fault.
api::Status EStopped() {
  return api::Status::Conflict("stimulator e-stopped: nothing is sent until the e-stop is cleared");
}

// A packet the stimulator's configuration cannot express (a value out of
// the packet's range): refused before anything is sent, and latched.
api::Status Unbuildable(const api::Status& built) {
  return api::Status::InvalidArgument("stimulator configuration: " + built.message());
}

}  // namespace

api::Status Stimulator::Send(const std::vector<std::uint8_t>& wire, bool stimulating) {
  if (faulted()) return fault();
  api::Status written;
  {
    std::lock_guard lock(write_mu_);
    if (stimulating && estop_.load()) return EStopped();
    // Handed to the port now: the device cannot have it earlier.
    const auto handed = std::chrono::steady_clock::now();
    written = port_.Write(wire);
    if (stimulating) last_command_written_ = handed;
  }
  if (!written.ok()) {
    return Fault(api::Status::Unavailable("stimulator lost: " + written.message()));
  }
  return api::Status::Ok();
}

api::Status Stimulator::AwaitAck(Command ack, std::vector<std::uint8_t>* data) {
  const auto deadline = std::chrono::steady_clock::now() + config_.reply_timeout;
  while (true) {
    while (const auto frame = reader_.Pop()) {
      const DecodeResult r = DecodePacket(*frame);
      if (!r.packet) {
        return Fault(
            api::Status::Unavailable("stimulator reply garbled: " + DecodeErrorName(*r.error)));
      }
      if (r.packet->command != static_cast<std::uint16_t>(ack)) continue;  // e.g. an e-stop's stop ack
      if (r.packet->packet_number != last_sent_number_) continue;
      const std::uint8_t result = r.packet->data.empty() ? 0xFF : r.packet->data[0];
      if (result != 0) {
        return Fault(api::Status::Unavailable("stimulator refused: " + ResultName(result)));
      }
      if (data != nullptr) *data = r.packet->data;
      return api::Status::Ok();
    }
    if (api::Status read = reader_.ReadReply(deadline, config_.reply_timeout); !read.ok()) {
      return Fault(std::move(read));
    }
  }
}

api::Status Stimulator::InitLowLevel() {
  last_sent_number_ = NextPacketNumber();
  const api::Result<std::vector<std::uint8_t>> wire = BuildLlInit(last_sent_number_);
  if (!wire.ok()) return Fault(Unbuildable(wire.status()));
  if (api::Status sent = Send(*wire, /*stimulating=*/true); !sent.ok()) return sent;
  if (api::Status acked = AwaitAck(Command::kLlInitAck); !acked.ok()) return acked;
  initialised_.store(!estop_.load());
  return api::Status::Ok();
}

api::Status Stimulator::Connect() {
  std::lock_guard io(io_mu_);
  if (config_.channel < 1 || config_.channel > kChannelCount) {
    return Fault(api::Status::InvalidArgument("channel must be 1–4, got " +
                                              std::to_string(config_.channel)));
  }
  if (config_.pulse_width_us < 1 || config_.pulse_width_us > kMaxPointTimeUs) {
    return Fault(api::Status::InvalidArgument("pulse width must be 1–4095 µs, got " +
                                              std::to_string(config_.pulse_width_us)));
  }
  if (api::Status opened = port_.Open(config_.port_path, ScienceMode4Settings()); !opened.ok()) {
    return Fault(std::move(opened));
  }
  if (api::Status init = InitLowLevel(); !init.ok()) return init;
  last_status_ = std::chrono::steady_clock::now();
  keeper_.Start(std::chrono::milliseconds(50), [this] { return Service(); });
  return api::Status::Ok();
}

api::Status Stimulator::CheckLimit(double stim_ma) {
  const double limit = std::min(kMaxCurrentMa, session_max_ma_.load());
  if (!(stim_ma >= 0.0) || stim_ma > limit) {
    return Fault(api::Status::FailedPrecondition("stimulator refused " + std::to_string(stim_ma) +
                                                 " mA: outside 0–" + std::to_string(limit) +
                                                 " mA"));
  }
  return api::Status::Ok();
}

api::Status Stimulator::SetAmplitude(double stim_ma) {
  if (faulted()) return fault();
  if (estopped()) return stim_ma == 0.0 ? api::Status::Ok() : EStopped();
  if (api::Status within = CheckLimit(stim_ma); !within.ok()) return within;
  amplitude_ma_.store(std::floor(stim_ma / kCurrentStepMa + 1e-9) * kCurrentStepMa);
  return api::Status::Ok();
}

api::Result<double> Stimulator::SinglePulse(double stim_ma) {
  std::lock_guard io(io_mu_);
  if (faulted()) return fault();
  if (estopped()) return EStopped();
  if (api::Status within = CheckLimit(stim_ma); !within.ok()) return within;
  if (!initialised_.load()) {
    if (api::Status init = InitLowLevel(); !init.ok()) return init;
  }
  const double current = std::floor(stim_ma / kCurrentStepMa + 1e-9) * kCurrentStepMa;
  const Point points[] = {{config_.pulse_width_us, current},
                          {kInterPhaseUs, 0.0},
                          {config_.pulse_width_us, -current}};
  last_sent_number_ = NextPacketNumber();
  const api::Result<std::vector<std::uint8_t>> wire =
      BuildLlChannelConfig(last_sent_number_, config_.channel - 1, 0, points);
  if (!wire.ok()) return Fault(Unbuildable(wire.status()));
  if (api::Status sent = Send(*wire, /*stimulating=*/true); !sent.ok()) return sent;
  if (api::Status acked = AwaitAck(Command::kLlChannelConfigAck); !acked.ok()) return acked;
  return current;
}

api::Status Stimulator::Service() {
  std::lock_guard io(io_mu_);
  if (faulted()) return fault();
  if (reader_.ReadAvailable() == FrameReader::ReadOutcome::kHungUp) {
    return Fault(api::Status::Unavailable(kStimulatorLost));
  }
  while (const auto frame = reader_.Pop()) {
    const DecodeResult r = DecodePacket(*frame);
    if (!r.packet) {
      return Fault(
          api::Status::Unavailable("stimulator reply garbled: " + DecodeErrorName(*r.error)));
    }
  }
  if (std::chrono::steady_clock::now() - last_status_ >= config_.status_interval) {
    return CheckStatusLocked();
  }
  return api::Status::Ok();
}

api::Status Stimulator::CheckStatusLocked() {
  const bool was_initialised = initialised_.load();
  last_status_ = std::chrono::steady_clock::now();
  last_sent_number_ = NextPacketNumber();
  if (api::Status sent = Send(BuildGetStimStatus(last_sent_number_), /*stimulating=*/false);
      !sent.ok()) {
    return sent;
  }
  std::vector<std::uint8_t> data;
  if (api::Status acked = AwaitAck(Command::kGetStimStatusAck, &data); !acked.ok()) return acked;
  if (data.size() < 2) {
    return Fault(api::Status::Unavailable(
        "stimulator status garbled: " + std::to_string(data.size()) + " data bytes"));
  }
  if (estop_.load()) return api::Status::Ok();  // an e-stop's Ll_Stop may land at any moment
  const auto expected = [](bool initialised) {
    return static_cast<std::uint8_t>(initialised ? StimStatus::kLlInitialized
                                                 : StimStatus::kUninitialized);
  };
  if (data[1] != expected(was_initialised) && data[1] != expected(initialised_.load())) {
    return Fault(api::Status::Unavailable(
        "stimulator " + StimStatusName(data[1]) + " where the driver set " +
        StimStatusName(expected(was_initialised)) + ": the device reset or stopped on its own"));
  }
  return api::Status::Ok();
}

}  // namespace fesbench::server::sciencemode4
