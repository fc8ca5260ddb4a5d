#include "server/bench/sciencemode2_packet.h"

#include <cmath>

namespace fesbench::server::sciencemode2 {
namespace {

bool IsReserved(std::uint8_t b) { return b == kStartByte || b == kStopByte || b == kStuffingByte; }

std::vector<std::uint8_t> Stuff(std::uint8_t packet_number, Command command,
                                std::span<const std::uint8_t> data) {
  std::vector<std::uint8_t> out;
  out.reserve(2 + 2 * data.size());
  AppendStuffed(out, packet_number);
  AppendStuffed(out, static_cast<std::uint8_t>(command));
  for (std::uint8_t b : data) AppendStuffed(out, b);
  return out;
}

api::Status OutOfRange(const std::string& field, const std::string& range, double got) {
  return api::Status::InvalidArgument(field + " must be " + range + ", got " + std::to_string(got));
}

}  // namespace

std::string ResultName(std::int8_t code) {
  switch (code) {
    case 0:
      return "No error";
    case -1:
      return "Transfer error";
    case -2:
      return "Parameter error";
    case -3:
      return "Wrong mode error";
    case -4:
      return "Motomed connection error";
    case -5:
      return "Incompatible protocol version";
    case -6:
      return "Invalid Motomed trainer";
    case -7:
      return "Motomed busy error";
    case -8:
      return "Busy error";
    default:
      return "result code " + std::to_string(code);
  }
}

std::string StimulationErrorName(std::int8_t code) {
  switch (code) {
    case -1:
      return "Emergency switch activated / not connected";
    case -2:
      return "Electrode error";
    case -3:
      return "Stimulation module error";
    default:
      return "stimulation error " + std::to_string(code);
  }
}

std::uint8_t Crc8(std::span<const std::uint8_t> bytes) {
  std::uint8_t crc = 0;
  for (std::uint8_t b : bytes) {
    crc ^= b;
    for (int i = 0; i < 8; ++i) {
      crc = (crc & 0x80) ? static_cast<std::uint8_t>((crc << 1) ^ 0x07)
                         : static_cast<std::uint8_t>(crc << 1);
    }
  }
  return crc;
}

void AppendStuffed(std::vector<std::uint8_t>& out, std::uint8_t byte) {
  if (IsReserved(byte)) {
    out.push_back(kStuffingByte);
    out.push_back(byte ^ kStuffingKey);
  } else {
    out.push_back(byte);
  }
}

std::vector<std::uint8_t> EncodePacket(std::uint8_t packet_number, Command command,
                                       std::span<const std::uint8_t> data) {
  const std::vector<std::uint8_t> body = Stuff(packet_number, command, data);
  std::vector<std::uint8_t> out;
  out.reserve(body.size() + 6);
  out.push_back(kStartByte);
  // §2.2: checksum and data length are always stuffed, so always 2 bytes.
  out.push_back(kStuffingByte);
  out.push_back(Crc8(body) ^ kStuffingKey);
  out.push_back(kStuffingByte);
  out.push_back(static_cast<std::uint8_t>(body.size()) ^ kStuffingKey);
  out.insert(out.end(), body.begin(), body.end());
  out.push_back(kStopByte);
  return out;
}

std::string DecodeErrorName(DecodeError error) {
  switch (error) {
    case DecodeError::kFraming:
      return "packet frame error";
    case DecodeError::kBadStuffing:
      return "bad byte stuffing";
    case DecodeError::kLength:
      return "data length error";
    case DecodeError::kChecksum:
      return "checksum error";
  }
  return "decode error";
}

DecodeResult DecodePacket(std::span<const std::uint8_t> frame) {
  // Start, 2 checksum, 2 length, packet number, command, stop: ≥ 8 bytes.
  if (frame.size() < 8 || frame.front() != kStartByte || frame.back() != kStopByte ||
      frame[1] != kStuffingByte || frame[3] != kStuffingByte) {
    return {std::nullopt, DecodeError::kFraming};
  }
  const std::uint8_t checksum = frame[2] ^ kStuffingKey;
  const std::uint8_t length = frame[4] ^ kStuffingKey;
  const auto body = frame.subspan(5, frame.size() - 6);
  if (body.size() != length) return {std::nullopt, DecodeError::kLength};
  if (Crc8(body) != checksum) return {std::nullopt, DecodeError::kChecksum};
  std::vector<std::uint8_t> plain;
  plain.reserve(body.size());
  for (std::size_t i = 0; i < body.size(); ++i) {
    if (body[i] == kStartByte || body[i] == kStopByte) return {std::nullopt, DecodeError::kFraming};
    if (body[i] != kStuffingByte) {
      plain.push_back(body[i]);
      continue;
    }
    if (i + 1 >= body.size()) return {std::nullopt, DecodeError::kBadStuffing};
    const std::uint8_t b = body[++i] ^ kStuffingKey;
    if (!IsReserved(b)) return {std::nullopt, DecodeError::kBadStuffing};
    plain.push_back(b);
  }
  if (plain.size() < 2) return {std::nullopt, DecodeError::kFraming};
  Packet packet;
  packet.packet_number = plain[0];
  packet.command = plain[1];
  packet.data.assign(plain.begin() + 2, plain.end());
  return {std::move(packet), std::nullopt};
}

std::vector<std::vector<std::uint8_t>> FrameSplitter::Feed(std::span<const std::uint8_t> bytes) {
  std::vector<std::vector<std::uint8_t>> frames;
  for (std::uint8_t b : bytes) {
    if (in_frame_ && after_stuffing_) {
      // The byte after a stuffing byte is data even when it equals a
      // constant: the stuffed checksum or length (§2.2) can be 0x0F or 0xF0.
      pending_.push_back(b);
      after_stuffing_ = false;
      continue;
    }
    if (b == kStartByte) {
      // §5.2 Packet frame error: a second start byte drops what came before.
      pending_.assign(1, b);
      in_frame_ = true;
      continue;
    }
    if (!in_frame_) continue;
    pending_.push_back(b);
    if (b == kStuffingByte) {
      after_stuffing_ = true;
    } else if (b == kStopByte) {
      frames.push_back(std::move(pending_));
      pending_.clear();
      in_frame_ = false;
    }
  }
  return frames;
}

std::vector<std::uint8_t> BuildInitAck(std::uint8_t packet_number, std::int8_t result) {
  const std::uint8_t data[] = {static_cast<std::uint8_t>(result)};
  return EncodePacket(packet_number, Command::kInitAck, data);
}

std::vector<std::uint8_t> BuildWatchdog(std::uint8_t packet_number) {
  return EncodePacket(packet_number, Command::kWatchdog, {});
}

std::vector<std::uint8_t> BuildStopChannelListMode(std::uint8_t packet_number) {
  return EncodePacket(packet_number, Command::kStopChannelListMode, {});
}

std::vector<std::uint8_t> BuildGetStimulationMode(std::uint8_t packet_number) {
  return EncodePacket(packet_number, Command::kGetStimulationMode, {});
}

std::string StimulationModeName(std::uint8_t mode) {
  switch (static_cast<StimulationMode>(mode)) {
    case StimulationMode::kStart:
      return "start mode";
    case StimulationMode::kChannelListInit:
      return "channel list initialised";
    case StimulationMode::kChannelListRun:
      return "channel list running";
  }
  return "mode " + std::to_string(mode);
}

api::Result<std::vector<std::uint8_t>> BuildInitChannelListMode(std::uint8_t packet_number,
                                                                const ChannelListInit& init) {
  if (init.low_frequency_factor > 7) {
    return OutOfRange("low_frequency_factor", "0–7", init.low_frequency_factor);
  }
  // §4.3: inter pulse interval = code·0.5 ms + 1.5 ms, code ∈ [0, 255].
  const double ipi_code = std::round((init.inter_pulse_interval_ms - 1.5) / 0.5);
  if (!(ipi_code >= 0 && ipi_code <= 255)) {
    return OutOfRange("inter_pulse_interval_ms", "1.5–129 ms", init.inter_pulse_interval_ms);
  }
  // §4.3: main stimulation interval = code·0.5 ms + 1 ms, code ∈ [0, 2048].
  const double main_code = std::round((init.main_interval_ms - 1.0) / 0.5);
  if (!(main_code >= 0 && main_code <= 2048)) {
    return OutOfRange("main_interval_ms", "1–1025 ms", init.main_interval_ms);
  }
  const auto main = static_cast<std::uint16_t>(main_code);
  const std::uint8_t data[] = {
      init.low_frequency_factor,
      init.active_channels,
      init.low_frequency_channels,
      static_cast<std::uint8_t>(ipi_code),
      static_cast<std::uint8_t>(main >> 8),    // byte 11: MSB
      static_cast<std::uint8_t>(main & 0xFF),  // byte 12: LSB
      static_cast<std::uint8_t>(init.as_fast_as_possible ? 1 : 0),
  };
  return EncodePacket(packet_number, Command::kInitChannelListMode, data);
}

api::Result<std::vector<std::uint8_t>> BuildStartChannelListMode(
    std::uint8_t packet_number, std::span<const ChannelPulse> pulses) {
  if (pulses.size() > kChannelCount) return OutOfRange("channels", "at most 8", pulses.size());
  std::vector<std::uint8_t> data;
  data.reserve(4 * pulses.size());
  for (const ChannelPulse& p : pulses) {
    if (p.mode > 2) return OutOfRange("mode", "0–2 (single, doublet, triplet)", p.mode);
    if (p.pulse_width_us < 0 || p.pulse_width_us > kMaxPulseWidthUs) {
      return OutOfRange("pulse_width_us", "0–500 µs", p.pulse_width_us);
    }
    if (p.current_ma < 0 || p.current_ma > kMaxCurrentMa) {
      return OutOfRange("current_ma", "0–130 mA", p.current_ma);
    }
    data.push_back(p.mode);
    data.push_back(static_cast<std::uint8_t>(p.pulse_width_us >> 8));    // byte 8: MSB
    data.push_back(static_cast<std::uint8_t>(p.pulse_width_us & 0xFF));  // byte 9: LSB
    data.push_back(static_cast<std::uint8_t>(p.current_ma));
  }
  return EncodePacket(packet_number, Command::kStartChannelListMode, data);
}

api::Result<std::vector<std::uint8_t>> BuildSinglePulse(std::uint8_t packet_number, int channel,
                                                        int pulse_width_us, int current_ma) {
  if (channel < 1 || channel > kChannelCount) return OutOfRange("channel", "1–8", channel);
  if (pulse_width_us < 0 || pulse_width_us > kMaxPulseWidthUs) {
    return OutOfRange("pulse_width_us", "0–500 µs", pulse_width_us);
  }
  if (current_ma < 0 || current_ma > kMaxCurrentMa)
    return OutOfRange("current_ma", "0–130 mA", current_ma);
  const std::vector<std::uint8_t> data{
      static_cast<std::uint8_t>(channel - 1),           // byte 7: channel number
      static_cast<std::uint8_t>(pulse_width_us >> 8),    // byte 8: MSB
      static_cast<std::uint8_t>(pulse_width_us & 0xFF),  // byte 9: LSB
      static_cast<std::uint8_t>(current_ma)};            // byte 10
  return EncodePacket(packet_number, Command::kSinglePulse, data);
}

std::optional<Reply> ParseReply(const Packet& packet) {
  Reply reply;
  reply.packet_number = packet.packet_number;
  reply.command = static_cast<Command>(packet.command);
  switch (reply.command) {
    case Command::kInit:  // byte 7: protocol version number (§4.1)
    case Command::kInitAck:
    case Command::kUnknownCommand:  // byte 7: echoed command (§4.1)
    case Command::kInitChannelListModeAck:
    case Command::kStartChannelListModeAck:
    case Command::kStopChannelListModeAck:
    case Command::kSinglePulseAck:
    case Command::kStimulationError:
      if (packet.data.size() != 1) return std::nullopt;
      reply.result = static_cast<std::int8_t>(packet.data[0]);
      return reply;
    case Command::kGetStimulationModeAck:
      // §4.2: byte 8 (mode) only if the result is 0.
      if (packet.data.empty()) return std::nullopt;
      reply.result = static_cast<std::int8_t>(packet.data[0]);
      if (reply.result == 0) {
        if (packet.data.size() != 2) return std::nullopt;
        reply.extra = packet.data[1];
      }
      return reply;
    default:
      return std::nullopt;
  }
}

}  // namespace fesbench::server::sciencemode2
