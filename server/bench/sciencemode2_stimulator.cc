#include "server/bench/sciencemode2_stimulator.h"

#include <algorithm>
#include <cmath>

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

void Stimulator::Fault(const std::string& reason) {
  {
    std::lock_guard lock(write_mu_);
    if (!faulted()) WriteStopLocked();
  }
  std::lock_guard lock(fault_mu_);
  if (fault_.empty()) fault_ = reason;
  faulted_.store(true);
}

std::string Stimulator::fault() const {
  std::lock_guard lock(fault_mu_);
  return fault_;
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

bool Stimulator::HandleSpontaneous(const Reply& reply) {
  if (reply.command == Command::kStimulationError) {
    Fault("stimulator reported: " + StimulationErrorName(reply.result));
    return false;
  }
  if (reply.command == Command::kInit && connected_.load()) {
    // §3.5: a device sends Init after it starts; once connected, it restarted.
    Fault("stimulator reset: the device sent Init again (it restarted and stopped stimulating)");
    return false;
  }
  return true;  // UnknownCommand for another packet, acks of an e-stop's stop: ignored
}

bool Stimulator::AwaitAck(Command command, Reply* ack) {
  const auto deadline = std::chrono::steady_clock::now() + config_.reply_timeout;
  while (true) {
    while (const auto frame = reader_.Pop()) {
      const DecodeResult r = DecodePacket(*frame);
      if (!r.packet) {
        Fault("stimulator reply garbled: " + DecodeErrorName(*r.error));
        return false;
      }
      const auto reply = ParseReply(*r.packet);
      if (!reply) continue;
      if (!HandleSpontaneous(*reply)) return false;
      if (reply->command == Command::kUnknownCommand && reply->packet_number == last_sent_number_) {
        Fault("stimulator did not know command " + std::to_string(static_cast<int>(reply->result)));
        return false;
      }
      if (reply->command != command) continue;
      // The ack of an e-stop's StopChannelListMode, sent from another thread.
      if (command == Command::kStopChannelListModeAck &&
          reply->packet_number != last_sent_number_) {
        continue;
      }
      if (reply->packet_number != last_sent_number_) {
        Fault("stimulator acknowledged packet " + std::to_string(reply->packet_number) +
              ", expected " + std::to_string(last_sent_number_));
        return false;
      }
      if (reply->result != 0) {
        Fault("stimulator refused: " + ResultName(reply->result));
        return false;
      }
      if (ack != nullptr) *ack = *reply;
      return true;
    }
    if (const std::string why = reader_.ReadReply(deadline, config_.reply_timeout); !why.empty()) {
      Fault(why);
      return false;
    }
  }
}

bool Stimulator::Connect() {
  std::lock_guard io(io_mu_);
  if (config_.channel < 1 || config_.channel > kChannelCount) {
    Fault("channel must be 1–8, got " + std::to_string(config_.channel));
    return false;
  }
  const std::string why = port_.Open(config_.port_path, ScienceMode2Settings());
  if (!why.empty()) {
    Fault(why);
    return false;
  }
  // §3.5: the device sends Init every InitRepetitionTime; answer InitAck 0.
  const auto deadline = std::chrono::steady_clock::now() + config_.connect_timeout;
  bool got_init = false;
  while (!got_init) {
    switch (reader_.ReadBefore(deadline)) {
      case FrameReader::ReadOutcome::kRead:
        break;
      case FrameReader::ReadOutcome::kTimedOut:
        Fault("stimulator timeout: no Init from the device within " +
              std::to_string(config_.connect_timeout.count()) + " ms (is ScienceMode2 selected?)");
        return false;
      case FrameReader::ReadOutcome::kHungUp:
        Fault(kStimulatorLost);
        return false;
    }
    while (const auto frame = reader_.Pop()) {
      const DecodeResult r = DecodePacket(*frame);
      if (!r.packet) continue;  // a partial first frame after opening the port
      const auto reply = ParseReply(*r.packet);
      if (reply && reply->command == Command::kInit) {
        got_init = true;
        if (!Send(BuildInitAck(reply->packet_number, 0), /*stimulating=*/false)) return false;
      }
    }
  }
  connected_.store(true);
  if (!InitChannelList()) return false;
  last_status_ = std::chrono::steady_clock::now();
  keeper_.Start(std::chrono::milliseconds(50), [this] { return KeepAlive(); });
  return true;
}

bool Stimulator::InitChannelList() {
  ChannelListInit init;
  init.active_channels = static_cast<std::uint8_t>(1u << (config_.channel - 1));
  init.main_interval_ms = 1000.0 / config_.pulse_rate_hz;
  try {
    const std::uint8_t number = NextPacketNumber();
    const auto wire = BuildInitChannelListMode(number, init);
    last_sent_number_ = number;
    if (!Send(wire, /*stimulating=*/true)) return false;
  } catch (const std::invalid_argument& e) {
    Fault(std::string("stimulator configuration: ") + e.what());
    return false;
  }
  if (!AwaitAck(Command::kInitChannelListModeAck)) return false;
  mode_ready_.store(!estop_.load());
  return true;
}

bool Stimulator::SetAmplitude(double stim_ma) {
  std::lock_guard io(io_mu_);
  if (faulted()) return false;
  if (estopped()) return stim_ma == 0.0;
  if (!CheckLimit(stim_ma)) return false;
  if (!mode_ready_.load() && !InitChannelList()) return false;
  // Down to the 1 mA step (§4.3): never more than commanded.
  const int current = static_cast<int>(std::floor(stim_ma + 1e-9));
  const ChannelPulse pulse{0, config_.pulse_width_us, current};
  last_sent_number_ = NextPacketNumber();
  if (!Send(BuildStartChannelListMode(last_sent_number_, std::span(&pulse, 1)),
            /*stimulating=*/true)) {
    return false;
  }
  if (!AwaitAck(Command::kStartChannelListModeAck)) return false;
  std::lock_guard lock(write_mu_);
  if (estop_.load()) return false;  // an e-stop's StopChannelListMode followed this start
  stimulating_.store(true);
  acknowledged_ma_.store(pulse.current_ma);
  return true;
}

bool Stimulator::CheckLimit(double stim_ma) {
  const double limit = std::min<double>(kMaxCurrentMa, session_max_ma_.load());
  if (!(stim_ma >= 0.0) || stim_ma > limit) {
    // Second line: the safety layer should have clamped; refuse and stop.
    Fault("stimulator refused " + std::to_string(stim_ma) + " mA: outside 0–" +
          std::to_string(limit) + " mA");
    return false;
  }
  return true;
}

std::optional<double> Stimulator::SinglePulse(double stim_ma) {
  std::lock_guard io(io_mu_);
  if (faulted() || estopped()) return std::nullopt;
  if (!CheckLimit(stim_ma)) return std::nullopt;
  if (stimulating_.load() || mode_ready_.load()) {
    last_sent_number_ = NextPacketNumber();
    if (!Send(BuildStopChannelListMode(last_sent_number_), /*stimulating=*/false) ||
        !AwaitAck(Command::kStopChannelListModeAck)) {
      return std::nullopt;
    }
    stimulating_.store(false);
    mode_ready_.store(false);
    acknowledged_ma_.store(0.0);
  }
  const int current = static_cast<int>(std::floor(stim_ma + 1e-9));
  last_sent_number_ = NextPacketNumber();
  if (!Send(BuildSinglePulse(last_sent_number_, config_.channel, config_.pulse_width_us, current),
            /*stimulating=*/true)) {
    return std::nullopt;
  }
  if (!AwaitAck(Command::kSinglePulseAck)) return std::nullopt;
  return current;
}

bool Stimulator::Stop() {
  std::lock_guard io(io_mu_);
  if (faulted()) return false;
  last_sent_number_ = NextPacketNumber();
  if (!Send(BuildStopChannelListMode(last_sent_number_), /*stimulating=*/false)) return false;
  if (!AwaitAck(Command::kStopChannelListModeAck)) return false;
  stimulating_.store(false);
  mode_ready_.store(false);
  acknowledged_ma_.store(0.0);
  return true;
}

bool Stimulator::KeepAlive() {
  std::lock_guard io(io_mu_);
  return KeepAliveLocked();
}

bool Stimulator::KeepAliveLocked() {
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
    const auto reply = ParseReply(*r.packet);
    if (reply && !HandleSpontaneous(*reply)) return false;
  }
  if (std::chrono::steady_clock::now() - last_status_ >= config_.status_interval) {
    return CheckModeLocked();
  }
  return true;
}

bool Stimulator::CheckModeLocked() {
  // The mode the driver set, read before asking: a command of this thread
  // cannot change it meanwhile (io_mu_ is held), an e-stop can.
  const StimulationMode expected = stimulating_.load()   ? StimulationMode::kChannelListRun
                                   : mode_ready_.load() ? StimulationMode::kChannelListInit
                                                        : StimulationMode::kStart;
  last_status_ = std::chrono::steady_clock::now();
  last_sent_number_ = NextPacketNumber();
  if (!Send(BuildGetStimulationMode(last_sent_number_), /*stimulating=*/false)) return false;
  Reply ack;
  if (!AwaitAck(Command::kGetStimulationModeAck, &ack)) return false;
  // An e-stop on another thread stops the device (start mode) at any moment.
  if (estop_.load()) return true;
  const StimulationMode now = stimulating_.load()   ? StimulationMode::kChannelListRun
                              : mode_ready_.load() ? StimulationMode::kChannelListInit
                                                   : StimulationMode::kStart;
  if (ack.extra != static_cast<std::uint8_t>(expected) &&
      ack.extra != static_cast<std::uint8_t>(now)) {
    Fault("stimulator in " + StimulationModeName(ack.extra) + " where the driver set " +
          StimulationModeName(static_cast<std::uint8_t>(expected)) +
          ": the device stopped or reset on its own");
    return false;
  }
  return true;
}

}  // namespace fesbench::server::sciencemode2
