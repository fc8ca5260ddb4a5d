#include "server/bench/sciencemode2_stimulator.h"

#include <cmath>

namespace fesbench::server::sciencemode2 {

Stimulator::Stimulator(StimulatorConfig config) : config_(std::move(config)) {}

Stimulator::~Stimulator() {
  if (stimulating_ && port_.is_open()) {
    (void)port_.Write(BuildStopChannelListMode(NextPacketNumber()));
  }
}

void Stimulator::Fault(const std::string& reason) {
  if (stimulating_ && port_.is_open()) {
    (void)port_.Write(BuildStopChannelListMode(NextPacketNumber()));
  }
  stimulating_ = false;
  acknowledged_ma_ = 0.0;
  if (fault_.empty()) fault_ = reason;
}

bool Stimulator::Send(const std::vector<std::uint8_t>& wire) {
  if (faulted()) return false;
  const std::string why = port_.Write(wire);
  if (!why.empty()) {
    Fault("stimulator lost: " + why);
    return false;
  }
  last_send_ = std::chrono::steady_clock::now();
  return true;
}

bool Stimulator::HandleSpontaneous(const Reply& reply) {
  if (reply.command == Command::kStimulationError) {
    Fault("stimulator reported: " + StimulationErrorName(reply.result));
    return false;
  }
  return true;  // Init repeats, UnknownCommand for another packet: ignored
}

bool Stimulator::AwaitAck(Command command) {
  const auto deadline = std::chrono::steady_clock::now() + config_.reply_timeout;
  std::uint8_t buffer[256];
  while (true) {
    while (!frames_.empty()) {
      const auto frame = std::move(frames_.front());
      frames_.erase(frames_.begin());
      const DecodeResult r = DecodePacket(frame);
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
      if (reply->packet_number != last_sent_number_) {
        Fault("stimulator acknowledged packet " + std::to_string(reply->packet_number) +
              ", expected " + std::to_string(last_sent_number_));
        return false;
      }
      if (reply->result != 0) {
        Fault("stimulator refused: " + ResultName(reply->result));
        return false;
      }
      return true;
    }
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      Fault("stimulator timeout: no reply within " + std::to_string(config_.reply_timeout.count()) +
            " ms");
      return false;
    }
    const int n = port_.Read(buffer, left);
    if (n < 0) {
      Fault("stimulator lost: the serial port hung up (cable pulled or device off)");
      return false;
    }
    for (auto& f : splitter_.Feed(std::span(buffer, static_cast<std::size_t>(n)))) {
      frames_.push_back(std::move(f));
    }
  }
}

bool Stimulator::Connect() {
  if (config_.channel < 1 || config_.channel > kChannelCount) {
    Fault("channel must be 1–8, got " + std::to_string(config_.channel));
    return false;
  }
  const std::string why = port_.Open(config_.port_path);
  if (!why.empty()) {
    Fault(why);
    return false;
  }
  // §3.5: the device sends Init every InitRepetitionTime; answer InitAck 0.
  const auto deadline = std::chrono::steady_clock::now() + config_.connect_timeout;
  std::uint8_t buffer[256];
  bool got_init = false;
  while (!got_init) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      Fault("stimulator timeout: no Init from the device within " +
            std::to_string(config_.connect_timeout.count()) + " ms (is ScienceMode2 selected?)");
      return false;
    }
    const int n = port_.Read(buffer, left);
    if (n < 0) {
      Fault("stimulator lost: the serial port hung up");
      return false;
    }
    for (auto& f : splitter_.Feed(std::span(buffer, static_cast<std::size_t>(n)))) {
      const DecodeResult r = DecodePacket(f);
      if (!r.packet) continue;  // a partial first frame after opening the port
      const auto reply = ParseReply(*r.packet);
      if (reply && reply->command == Command::kInit) {
        got_init = true;
        if (!Send(BuildInitAck(reply->packet_number, 0))) return false;
      }
    }
  }
  ChannelListInit init;
  init.active_channels = static_cast<std::uint8_t>(1u << (config_.channel - 1));
  init.main_interval_ms = 1000.0 / config_.pulse_rate_hz;
  last_sent_number_ = NextPacketNumber();
  try {
    if (!Send(BuildInitChannelListMode(last_sent_number_, init))) return false;
  } catch (const std::invalid_argument& e) {
    Fault(std::string("stimulator configuration: ") + e.what());
    return false;
  }
  return AwaitAck(Command::kInitChannelListModeAck);
}

bool Stimulator::SetAmplitude(double stim_ma) {
  if (faulted()) return false;
  const double limit = std::min<double>(kMaxCurrentMa, config_.session_max_ma);
  if (!(stim_ma >= 0.0) || stim_ma > limit) {
    // Second line: the safety layer should have clamped; refuse and stop.
    Fault("stimulator refused " + std::to_string(stim_ma) + " mA: outside 0–" +
          std::to_string(limit) + " mA");
    return false;
  }
  const ChannelPulse pulse{0, config_.pulse_width_us, static_cast<int>(std::lround(stim_ma))};
  last_sent_number_ = NextPacketNumber();
  if (!Send(BuildStartChannelListMode(last_sent_number_, std::span(&pulse, 1)))) return false;
  if (!AwaitAck(Command::kStartChannelListModeAck)) return false;
  stimulating_ = true;
  acknowledged_ma_ = pulse.current_ma;
  return true;
}

bool Stimulator::Stop() {
  if (faulted()) return false;
  last_sent_number_ = NextPacketNumber();
  if (!Send(BuildStopChannelListMode(last_sent_number_))) return false;
  if (!AwaitAck(Command::kStopChannelListModeAck)) return false;
  stimulating_ = false;
  acknowledged_ma_ = 0.0;
  return true;
}

bool Stimulator::KeepAlive() {
  if (faulted()) return false;
  std::uint8_t buffer[256];
  const int n = port_.Read(buffer, std::chrono::milliseconds(0));
  if (n < 0) {
    Fault("stimulator lost: the serial port hung up (cable pulled or device off)");
    return false;
  }
  for (auto& f : splitter_.Feed(std::span(buffer, static_cast<std::size_t>(n)))) {
    const DecodeResult r = DecodePacket(f);
    if (!r.packet) {
      Fault("stimulator reply garbled: " + DecodeErrorName(*r.error));
      return false;
    }
    const auto reply = ParseReply(*r.packet);
    if (reply && !HandleSpontaneous(*reply)) return false;
  }
  if (std::chrono::steady_clock::now() - last_send_ >= config_.watchdog_interval) {
    return Send(BuildWatchdog(NextPacketNumber()));
  }
  return true;
}

}  // namespace fesbench::server::sciencemode2
