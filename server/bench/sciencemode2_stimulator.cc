#include "server/bench/sciencemode2_stimulator.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace fesbench::server::sciencemode2 {

double DevicePulseRateHz(double requested_hz) {
  const double code = std::round((1000.0 / requested_hz - 1.0) / 0.5);  // §4.3
  return 1000.0 / (1.0 + 0.5 * code);
}

Stimulator::Stimulator(StimulatorConfig config)
    : config_(std::move(config)), session_max_ma_(config_.session_max_ma) {}

Stimulator::~Stimulator() {
  keeper_.Stop();  // no duty runs while the device is stopped below
  std::lock_guard lock(write_mu_);
  if (stimulating_.load()) WriteStopLocked();
}

void Stimulator::WriteStopLocked() {
  if (port_.is_open()) (void)port_.Write(BuildStopChannelListMode(NextPacketNumber()));
  stimulating_.store(false);
  mode_ready_.store(false);
  acknowledged_ma_.store(0.0);
}

void Stimulator::EmergencyStop() {
  std::lock_guard lock(write_mu_);
  estop_.store(true);
  if (!faulted()) WriteStopLocked();
}

api::Status Stimulator::Fault(api::Status reason) {
  {
    std::lock_guard lock(write_mu_);
    if (!faulted()) WriteStopLocked();
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

api::Status Stimulator::HandleSpontaneous(const Reply& reply) {
  if (reply.command == Command::kStimulationError) {
    return Fault(
        api::Status::Unavailable("stimulator reported: " + StimulationErrorName(reply.result)));
  }
  if (reply.command == Command::kInit && connected_.load()) {
    // §3.5: a device sends Init after it starts; once connected, it restarted.
    return Fault(api::Status::Unavailable(
        "stimulator reset: the device sent Init again (it restarted and stopped stimulating)"));
  }
  return api::Status::Ok();  // UnknownCommand for another packet, acks of an e-stop's stop: ignored
}

api::Status Stimulator::AwaitAck(Command command, Reply* ack) {
  const auto deadline = std::chrono::steady_clock::now() + config_.reply_timeout;
  while (true) {
    while (const auto frame = reader_.Pop()) {
      const DecodeResult r = DecodePacket(*frame);
      if (!r.packet) {
        return Fault(
            api::Status::Unavailable("stimulator reply garbled: " + DecodeErrorName(*r.error)));
      }
      const auto reply = ParseReply(*r.packet);
      if (!reply) continue;
      if (api::Status spontaneous = HandleSpontaneous(*reply); !spontaneous.ok()) {
        return spontaneous;
      }
      if (reply->command == Command::kUnknownCommand && reply->packet_number == last_sent_number_) {
        return Fault(api::Status::Unavailable("stimulator did not know command " +
                                              std::to_string(static_cast<int>(reply->result))));
      }
      if (reply->command != command) continue;
      // The ack of an e-stop's StopChannelListMode, sent from another thread.
      if (command == Command::kStopChannelListModeAck &&
          reply->packet_number != last_sent_number_) {
        continue;
      }
      if (reply->packet_number != last_sent_number_) {
        return Fault(api::Status::Unavailable("stimulator acknowledged packet " +
                                              std::to_string(reply->packet_number) + ", expected " +
                                              std::to_string(last_sent_number_)));
      }
      if (reply->result != 0) {
        return Fault(api::Status::Unavailable("stimulator refused: " + ResultName(reply->result)));
      }
      if (ack != nullptr) *ack = *reply;
      return api::Status::Ok();
    }
    if (api::Status read = reader_.ReadReply(deadline, config_.reply_timeout); !read.ok()) {
      return Fault(std::move(read));
    }
  }
}

api::Status Stimulator::Connect() {
  std::lock_guard io(io_mu_);
  if (config_.channel < 1 || config_.channel > kChannelCount) {
    return Fault(api::Status::InvalidArgument("channel must be 1–8, got " +
                                              std::to_string(config_.channel)));
  }
  if (api::Status opened = port_.Open(config_.port_path, ScienceMode2Settings()); !opened.ok()) {
    return Fault(std::move(opened));
  }
  // §3.5: the device sends Init every InitRepetitionTime; answer InitAck 0.
  const auto deadline = std::chrono::steady_clock::now() + config_.connect_timeout;
  bool got_init = false;
  while (!got_init) {
    switch (reader_.ReadBefore(deadline)) {
      case FrameReader::ReadOutcome::kRead:
        break;
      case FrameReader::ReadOutcome::kTimedOut:
        return Fault(api::Status::Unavailable(
            "stimulator timeout: no Init from the device within " +
            std::to_string(config_.connect_timeout.count()) + " ms (is ScienceMode2 selected?)"));
      case FrameReader::ReadOutcome::kHungUp:
        return Fault(api::Status::Unavailable(kStimulatorLost));
    }
    while (const auto frame = reader_.Pop()) {
      const DecodeResult r = DecodePacket(*frame);
      if (!r.packet) continue;  // a partial first frame after opening the port
      const auto reply = ParseReply(*r.packet);
      if (reply && reply->command == Command::kInit) {
        got_init = true;
        if (api::Status sent = Send(BuildInitAck(reply->packet_number, 0), /*stimulating=*/false);
            !sent.ok()) {
          return sent;
        }
      }
    }
  }
  connected_.store(true);
  if (api::Status init = InitChannelList(); !init.ok()) return init;
  last_status_ = std::chrono::steady_clock::now();
  keeper_.Start(std::chrono::milliseconds(50), [this] { return KeepAlive(); });
  return api::Status::Ok();
}

api::Status Stimulator::InitChannelList() {
  ChannelListInit init;
  init.active_channels = static_cast<std::uint8_t>(1u << (config_.channel - 1));
  init.main_interval_ms = 1000.0 / config_.pulse_rate_hz;
  const std::uint8_t number = NextPacketNumber();
  const api::Result<std::vector<std::uint8_t>> wire = BuildInitChannelListMode(number, init);
  if (!wire.ok()) return Fault(Unbuildable(wire.status()));
  last_sent_number_ = number;
  if (api::Status sent = Send(*wire, /*stimulating=*/true); !sent.ok()) return sent;
  if (api::Status acked = AwaitAck(Command::kInitChannelListModeAck); !acked.ok()) return acked;
  mode_ready_.store(!estop_.load());
  return api::Status::Ok();
}

api::Status Stimulator::SetAmplitude(double stim_ma) {
  std::lock_guard io(io_mu_);
  if (faulted()) return fault();
  if (estopped()) return stim_ma == 0.0 ? api::Status::Ok() : EStopped();
  if (api::Status within = CheckLimit(stim_ma); !within.ok()) return within;
  if (!mode_ready_.load()) {
    if (api::Status init = InitChannelList(); !init.ok()) return init;
  }
  // Down to the 1 mA step (§4.3): never more than commanded.
  const int current = static_cast<int>(std::floor(stim_ma + 1e-9));
  const ChannelPulse pulse{0, config_.pulse_width_us, current};
  last_sent_number_ = NextPacketNumber();
  const api::Result<std::vector<std::uint8_t>> wire =
      BuildStartChannelListMode(last_sent_number_, std::span(&pulse, 1));
  if (!wire.ok()) return Fault(Unbuildable(wire.status()));
  if (api::Status sent = Send(*wire, /*stimulating=*/true); !sent.ok()) return sent;
  if (api::Status acked = AwaitAck(Command::kStartChannelListModeAck); !acked.ok()) return acked;
  std::lock_guard lock(write_mu_);
  if (estop_.load()) return EStopped();  // an e-stop's StopChannelListMode followed this start
  stimulating_.store(true);
  acknowledged_ma_.store(pulse.current_ma);
  return api::Status::Ok();
}

api::Status Stimulator::CheckLimit(double stim_ma) {
  const double limit = std::min<double>(kMaxCurrentMa, session_max_ma_.load());
  if (!(stim_ma >= 0.0) || stim_ma > limit) {
    // Second line: the safety layer should have clamped; refuse and stop.
    return Fault(api::Status::FailedPrecondition("stimulator refused " + std::to_string(stim_ma) +
                                                 " mA: outside 0–" + std::to_string(limit) +
                                                 " mA"));
  }
  return api::Status::Ok();
}

api::Result<double> Stimulator::SinglePulse(double stim_ma) {
  std::lock_guard io(io_mu_);
  if (faulted()) return fault();
  if (estopped()) return EStopped();
  if (api::Status within = CheckLimit(stim_ma); !within.ok()) return within;
  if (stimulating_.load() || mode_ready_.load()) {
    last_sent_number_ = NextPacketNumber();
    if (api::Status sent = Send(BuildStopChannelListMode(last_sent_number_), /*stimulating=*/false);
        !sent.ok()) {
      return sent;
    }
    if (api::Status acked = AwaitAck(Command::kStopChannelListModeAck); !acked.ok()) return acked;
    stimulating_.store(false);
    mode_ready_.store(false);
    acknowledged_ma_.store(0.0);
  }
  const int current = static_cast<int>(std::floor(stim_ma + 1e-9));
  last_sent_number_ = NextPacketNumber();
  const api::Result<std::vector<std::uint8_t>> wire =
      BuildSinglePulse(last_sent_number_, config_.channel, config_.pulse_width_us, current);
  if (!wire.ok()) return Fault(Unbuildable(wire.status()));
  if (api::Status sent = Send(*wire, /*stimulating=*/true); !sent.ok()) return sent;
  if (api::Status acked = AwaitAck(Command::kSinglePulseAck); !acked.ok()) return acked;
  return static_cast<double>(current);
}

api::Status Stimulator::Stop() {
  std::lock_guard io(io_mu_);
  if (faulted()) return fault();
  last_sent_number_ = NextPacketNumber();
  if (api::Status sent = Send(BuildStopChannelListMode(last_sent_number_), /*stimulating=*/false);
      !sent.ok()) {
    return sent;
  }
  if (api::Status acked = AwaitAck(Command::kStopChannelListModeAck); !acked.ok()) return acked;
  stimulating_.store(false);
  mode_ready_.store(false);
  acknowledged_ma_.store(0.0);
  return api::Status::Ok();
}

api::Status Stimulator::KeepAlive() {
  std::lock_guard io(io_mu_);
  return KeepAliveLocked();
}

api::Status Stimulator::KeepAliveLocked() {
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
    const auto reply = ParseReply(*r.packet);
    if (!reply) continue;
    if (api::Status spontaneous = HandleSpontaneous(*reply); !spontaneous.ok()) return spontaneous;
  }
  if (std::chrono::steady_clock::now() - last_status_ >= config_.status_interval) {
    return CheckModeLocked();
  }
  return api::Status::Ok();
}

api::Status Stimulator::CheckModeLocked() {
  // The mode the driver set, read before asking: a command of this thread
  // cannot change it meanwhile (io_mu_ is held), an e-stop can.
  const StimulationMode expected = stimulating_.load()   ? StimulationMode::kChannelListRun
                                   : mode_ready_.load() ? StimulationMode::kChannelListInit
                                                        : StimulationMode::kStart;
  last_status_ = std::chrono::steady_clock::now();
  last_sent_number_ = NextPacketNumber();
  if (api::Status sent = Send(BuildGetStimulationMode(last_sent_number_), /*stimulating=*/false);
      !sent.ok()) {
    return sent;
  }
  Reply ack;
  if (api::Status acked = AwaitAck(Command::kGetStimulationModeAck, &ack); !acked.ok()) {
    return acked;
  }
  // An e-stop on another thread stops the device (start mode) at any moment.
  if (estop_.load()) return api::Status::Ok();
  const StimulationMode now = stimulating_.load()   ? StimulationMode::kChannelListRun
                              : mode_ready_.load() ? StimulationMode::kChannelListInit
                                                   : StimulationMode::kStart;
  if (ack.extra != static_cast<std::uint8_t>(expected) &&
      ack.extra != static_cast<std::uint8_t>(now)) {
    return Fault(api::Status::Unavailable("stimulator in " + StimulationModeName(ack.extra) +
                                          " where the driver set " +
                                          StimulationModeName(static_cast<std::uint8_t>(expected)) +
                                          ": the device stopped or reset on its own"));
  }
  return api::Status::Ok();
}

}  // namespace fesbench::server::sciencemode2
