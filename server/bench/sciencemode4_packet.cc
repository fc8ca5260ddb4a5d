#include "server/bench/sciencemode4_packet.h"

#include <cmath>

#include "server/bench/sciencemode2_packet.h"

namespace fesbench::server::sciencemode4 {
namespace {

constexpr std::uint8_t kStart = 0xF0;
constexpr std::uint8_t kStop = 0x0F;
constexpr std::uint8_t kStuffing = 0x81;
constexpr std::uint8_t kKey = 0x55;
constexpr std::size_t kHeaderBytes = 9;  // start, stuffed length, stuffed checksum

api::Status OutOfRange(const std::string& field, const std::string& range, double got) {
  return api::Status::InvalidArgument(field + " must be " + range + ", got " + std::to_string(got));
}

}  // namespace

std::string ResultName(std::uint8_t code) {
  switch (static_cast<Result>(code)) {
    case Result::kSuccessful: return "Successful";
    case Result::kTransferError: return "Transfer error (checksum or length mismatch)";
    case Result::kParameterError: return "Parameter error";
    case Result::kProtocolError: return "Protocol error";
    case Result::kUcStimTimeoutError: return "Stimulation timeout error";
    case Result::kNotInitializedError: return "Not initialised error";
    case Result::kHvError: return "High-voltage error";
    case Result::kElectrodeError: return "Electrode error";
    case Result::kInvalidCmdError: return "Invalid command error";
  }
  return "result code " + std::to_string(code);
}

std::uint16_t Crc16(std::span<const std::uint8_t> bytes) {
  std::uint16_t crc = 0;
  for (std::uint8_t b : bytes) {
    crc = static_cast<std::uint16_t>(crc ^ (b << 8));
    for (int i = 0; i < 8; ++i) {
      crc = (crc & 0x8000) ? static_cast<std::uint16_t>((crc << 1) ^ 0x1021)
                           : static_cast<std::uint16_t>(crc << 1);
    }
  }
  return crc;
}

std::vector<std::uint8_t> EncodePacket(std::uint8_t packet_number, Command command,
                                       std::span<const std::uint8_t> data) {
  const auto cmd = static_cast<std::uint16_t>(command);
  std::vector<std::uint8_t> body;
  body.reserve(2 * (2 + data.size()));
  sciencemode2::AppendStuffed(
      body, static_cast<std::uint8_t>(((packet_number << 2) & 0xFC) | ((cmd >> 8) & 0x03)));
  sciencemode2::AppendStuffed(body, static_cast<std::uint8_t>(cmd & 0xFF));
  for (std::uint8_t b : data) sciencemode2::AppendStuffed(body, b);
  const std::size_t length = kHeaderBytes + body.size() + 1;
  const std::uint16_t crc = Crc16(body);
  const std::uint8_t header[kHeaderBytes] = {kStart,
                                             kStuffing,
                                             static_cast<std::uint8_t>((length >> 8) ^ kKey),
                                             kStuffing,
                                             static_cast<std::uint8_t>((length & 0xFF) ^ kKey),
                                             kStuffing,
                                             static_cast<std::uint8_t>((crc >> 8) ^ kKey),
                                             kStuffing,
                                             static_cast<std::uint8_t>((crc & 0xFF) ^ kKey)};
  std::vector<std::uint8_t> wire;
  wire.reserve(length);
  for (std::uint8_t b : header) wire.push_back(b);
  for (std::uint8_t b : body) wire.push_back(b);
  wire.push_back(kStop);
  return wire;
}

std::string DecodeErrorName(DecodeError error) {
  switch (error) {
    case DecodeError::kFraming: return "framing error";
    case DecodeError::kBadStuffing: return "stuffing error";
    case DecodeError::kLength: return "length error";
    case DecodeError::kChecksum: return "checksum error";
  }
  return "decode error";
}

DecodeResult DecodePacket(std::span<const std::uint8_t> frame) {
  DecodeResult r;
  if (frame.size() < kHeaderBytes + 3 || frame.front() != kStart || frame.back() != kStop ||
      frame[1] != kStuffing || frame[3] != kStuffing || frame[5] != kStuffing ||
      frame[7] != kStuffing) {
    r.error = DecodeError::kFraming;
    return r;
  }
  const std::size_t length = (static_cast<std::size_t>(frame[2] ^ kKey) << 8) | (frame[4] ^ kKey);
  if (length != frame.size()) {
    r.error = DecodeError::kLength;
    return r;
  }
  const auto stuffed = frame.subspan(kHeaderBytes, frame.size() - kHeaderBytes - 1);
  const std::uint16_t crc = static_cast<std::uint16_t>(((frame[6] ^ kKey) << 8) | (frame[8] ^ kKey));
  if (Crc16(stuffed) != crc) {
    r.error = DecodeError::kChecksum;
    return r;
  }
  std::vector<std::uint8_t> body;
  for (std::size_t i = 0; i < stuffed.size(); ++i) {
    if (stuffed[i] == kStuffing) {
      if (i + 1 == stuffed.size()) {
        r.error = DecodeError::kBadStuffing;
        return r;
      }
      body.push_back(stuffed[++i] ^ kKey);
    } else {
      body.push_back(stuffed[i]);
    }
  }
  if (body.size() < 2) {
    r.error = DecodeError::kFraming;
    return r;
  }
  Packet p;
  p.packet_number = static_cast<std::uint8_t>(body[0] >> 2);
  p.command = static_cast<std::uint16_t>(((body[0] & 0x03) << 8) | body[1]);
  p.data.assign(body.begin() + 2, body.end());
  r.packet = std::move(p);
  return r;
}

api::Result<std::vector<std::uint8_t>> BuildLlInit(std::uint8_t packet_number,
                                                   int high_voltage_level) {
  if (high_voltage_level < 0 || high_voltage_level > 7) {
    return OutOfRange("high_voltage_level", "0–7", high_voltage_level);
  }
  const std::uint8_t data[] = {static_cast<std::uint8_t>((high_voltage_level & 0x07) << 1)};
  return EncodePacket(packet_number, Command::kLlInit, data);
}

api::Result<std::vector<std::uint8_t>> BuildLlChannelConfig(std::uint8_t packet_number, int channel,
                                                            int connector,
                                                            std::span<const Point> points) {
  if (channel < 0 || channel >= kChannelCount) return OutOfRange("channel", "0–3", channel);
  if (connector < 0 || connector > 1) return OutOfRange("connector", "0–1", connector);
  if (points.empty() || points.size() > static_cast<std::size_t>(kMaxPoints)) {
    return OutOfRange("points", "1–16 points", static_cast<double>(points.size()));
  }
  std::vector<std::uint8_t> data;
  data.push_back(static_cast<std::uint8_t>(0x80 | ((channel << 5) & 0x60) |
                                           ((connector << 4) & 0x10) |
                                           ((points.size() - 1) & 0x0F)));
  for (const Point& p : points) {
    if (p.time_us < 0 || p.time_us > kMaxPointTimeUs)
      return OutOfRange("time_us", "0–4095 µs", p.time_us);
    if (!(std::abs(p.current_ma) <= kMaxCurrentMa)) {
      return OutOfRange("current_ma", "−150–150 mA", p.current_ma);
    }
    // 2·I + 300: 0.5 mA steps, 0 … 600 in 10 bits.
    const auto code = static_cast<std::uint16_t>(std::lround(p.current_ma * 2.0 + 300.0));
    data.push_back(static_cast<std::uint8_t>(p.time_us >> 4));
    data.push_back(static_cast<std::uint8_t>(((p.time_us << 4) & 0xF0) | ((code >> 6) & 0x0F)));
    data.push_back(static_cast<std::uint8_t>((code << 2) & 0xFC));
    data.push_back(0);  // interpolation mode 0: jump
  }
  return EncodePacket(packet_number, Command::kLlChannelConfig, data);
}

std::vector<std::uint8_t> BuildLlStop(std::uint8_t packet_number) {
  return EncodePacket(packet_number, Command::kLlStop, {});
}

std::vector<std::uint8_t> BuildGetStimStatus(std::uint8_t packet_number) {
  return EncodePacket(packet_number, Command::kGetStimStatus, {});
}

std::string StimStatusName(std::uint8_t status) {
  switch (static_cast<StimStatus>(status)) {
    case StimStatus::kUninitialized:
      return "uninitialised";
    case StimStatus::kLlInitialized:
      return "low level initialised";
    case StimStatus::kMlInitialized:
      return "mid level initialised";
    case StimStatus::kMlRunning:
      return "mid level running";
  }
  return "status " + std::to_string(status);
}

std::vector<std::uint8_t> BuildGetStimStatusAck(std::uint8_t packet_number, Result result,
                                                StimStatus status, std::uint8_t high_voltage) {
  const std::uint8_t data[] = {static_cast<std::uint8_t>(result), static_cast<std::uint8_t>(status),
                               high_voltage};
  return EncodePacket(packet_number, Command::kGetStimStatusAck, data);
}

std::vector<std::uint8_t> BuildAck(std::uint8_t packet_number, Command ack, Result result) {
  const std::uint8_t data[] = {static_cast<std::uint8_t>(result)};
  return EncodePacket(packet_number, ack, data);
}

std::vector<std::uint8_t> BuildLlChannelConfigAck(std::uint8_t packet_number, Result result,
                                                  int channel, int connector) {
  const std::uint8_t data[] = {static_cast<std::uint8_t>(result),
                               static_cast<std::uint8_t>(((connector & 0x0F) << 4) |
                                                         (channel & 0x0F)),
                               0};  // measurement: none
  return EncodePacket(packet_number, Command::kLlChannelConfigAck, data);
}

std::optional<ChannelConfig> ParseLlChannelConfig(std::span<const std::uint8_t> data) {
  if (data.empty()) return std::nullopt;
  ChannelConfig c;
  c.enable = (data[0] & 0x80) != 0;
  c.channel = (data[0] & 0x60) >> 5;
  c.connector = (data[0] & 0x10) >> 4;
  if (!c.enable) return c;
  const std::size_t n = (data[0] & 0x0F) + 1;
  if (data.size() != 1 + 4 * n) return std::nullopt;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* b = data.data() + 1 + 4 * i;
    Point p;
    p.time_us = (b[0] << 4) | (b[1] >> 4);
    const int code = ((b[1] & 0x0F) << 6) | (b[2] >> 2);
    p.current_ma = (code - 300) / 2.0;
    c.points.push_back(p);
  }
  return c;
}

}  // namespace fesbench::server::sciencemode4
