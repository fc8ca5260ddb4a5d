#pragma once

/// @file
/// ScienceMode2 (Hasomed RehaStim2) packet layer: pure functions, no I/O.
/// Everything here follows "ScienceMode2 – Description and Protocol",
/// version 1.24, 2012-12-12 (Hasomed; public in GitHub ScienceMode/ScienceMode2,
/// 02_Description Protocol/). Section numbers below refer to that document.

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "api/status.h"

namespace fesbench::server::sciencemode2 {

// Table 6 (§2.2): byte constants.
inline constexpr std::uint8_t kStartByte = 0xF0;
inline constexpr std::uint8_t kStopByte = 0x0F;
inline constexpr std::uint8_t kStuffingByte = 0x81;
inline constexpr std::uint8_t kStuffingKey = 0x55;

/// §3.1 and §3.3: command numbers (decimal in the description).
enum class Command : std::uint8_t {
  kInit = 1,
  kInitAck = 2,
  kUnknownCommand = 3,
  kWatchdog = 4,
  kGetStimulationMode = 10,
  kGetStimulationModeAck = 11,
  kInitChannelListMode = 30,
  kInitChannelListModeAck = 31,
  kStartChannelListMode = 32,
  kStartChannelListModeAck = 33,
  kStopChannelListMode = 34,
  kStopChannelListModeAck = 35,
  kSinglePulse = 36,
  kSinglePulseAck = 37,
  kStimulationError = 38,
};

/// §5.1: result codes of the response commands (signed byte on the wire).
enum class Result : std::int8_t {
  kOk = 0,
  kTransferError = -1,
  kParameterError = -2,
  kWrongModeError = -3,
  kMotomedConnectionError = -4,
  kIncompatibleVersion = -5,
  kInvalidMotomedTrainer = -6,
  kMotomedBusyError = -7,
  kBusyError = -8,
};

/// "Transfer error", "Parameter error", … as §5.1 names them;
/// "result code N" for codes §5.1 does not list.
std::string ResultName(std::int8_t code);

/// §4.3 StimulationError: "Emergency switch activated / not connected",
/// "Electrode error", "Stimulation module error"; "stimulation error N" else.
std::string StimulationErrorName(std::int8_t code);

// §1.2 Table 1 and §4.3: device limits.
inline constexpr int kMaxCurrentMa = 130;     ///< [0, 130] mA in 1 mA steps.
inline constexpr int kMaxPulseWidthUs = 500;  ///< [0, 500] µs (device floors to 20).
inline constexpr int kChannelCount = 8;

/// CRC-8-CCITT, polynomial x⁸ + x² + x + 1 (0x07), initial value 0, no
/// reflection, no final XOR (§2.2).
std::uint8_t Crc8(std::span<const std::uint8_t> bytes);

/// Appends `byte` to `out`, stuffed if it is one of the Table 6 constants
/// other than the stuffing key: 0x81 then byte ^ 0x55 (§2.2).
void AppendStuffed(std::vector<std::uint8_t>& out, std::uint8_t byte);

/// One whole packet on the wire (§2.2 Table 5): start byte; stuffing byte and
/// checksum ^ key; stuffing byte and data length ^ key; stuffed packet
/// number, command and data; stop byte. Checksum and data length are
/// computed over the *stuffed* packet number, command and data (§2.2).
std::vector<std::uint8_t> EncodePacket(std::uint8_t packet_number, Command command,
                                       std::span<const std::uint8_t> data);

/// A decoded packet.
struct Packet {
  std::uint8_t packet_number = 0;
  std::uint8_t command = 0;  ///< raw, may be a number §3 does not list.
  std::vector<std::uint8_t> data;
};

/// Why a frame did not decode.
enum class DecodeError {
  kFraming,      ///< no start/stop byte where Table 5 wants one, or too short.
  kBadStuffing,  ///< a stuffing byte at the end or before a non-constant.
  kLength,       ///< data length does not match (§5.2 Data length error).
  kChecksum,     ///< CRC mismatch (§5.2 Checksum error).
};
std::string DecodeErrorName(DecodeError error);

struct DecodeResult {
  std::optional<Packet> packet;
  std::optional<DecodeError> error;
};

/// Decodes one frame from its start byte to its stop byte inclusive.
DecodeResult DecodePacket(std::span<const std::uint8_t> frame);

/// Splits a byte stream into frames start…stop. A second start byte before a
/// stop byte discards the bytes before it (§5.2 Packet frame error); a byte
/// after a stuffing byte is never a delimiter. Bytes
/// of an unfinished frame stay buffered for the next Feed.
class FrameSplitter {
 public:
  /// Returns every complete frame in the stream so far.
  std::vector<std::vector<std::uint8_t>> Feed(std::span<const std::uint8_t> bytes);

 private:
  std::vector<std::uint8_t> pending_;
  bool in_frame_ = false;
  bool after_stuffing_ = false;  ///< the last byte was a stuffing byte.
};

// ---- Command builders (§4.1, §4.3); each returns the wire bytes. ----

/// InitAck (§4.1): PC's answer to the device's Init; result 0 accepts.
std::vector<std::uint8_t> BuildInitAck(std::uint8_t packet_number, std::int8_t result);
/// Watchdog (§4.1): keeps the connection inside WatchdogTimeout (§2.3).
std::vector<std::uint8_t> BuildWatchdog(std::uint8_t packet_number);
/// StopChannelListMode (§4.3).
std::vector<std::uint8_t> BuildStopChannelListMode(std::uint8_t packet_number);
/// GetStimulationMode (§4.2): no data; the device answers
/// GetStimulationModeAck with its result and, if 0, its mode (StimulationMode).
std::vector<std::uint8_t> BuildGetStimulationMode(std::uint8_t packet_number);

/// The device's mode in GetStimulationModeAck's byte 8 (§4.2).
enum class StimulationMode : std::uint8_t {
  kStart = 0,             ///< start mode: no channel list initialised (single pulses only).
  kChannelListInit = 1,   ///< channel-list mode initialised, not running.
  kChannelListRun = 2,    ///< channel-list mode running.
};
/// "start mode", "channel list initialised", "channel list running", or "mode N".
std::string StimulationModeName(std::uint8_t mode);

/// InitChannelListMode parameters (§4.3, Table 2).
struct ChannelListInit {
  std::uint8_t low_frequency_factor = 0;    ///< [0, 7].
  std::uint8_t active_channels = 0;         ///< bit 0 = channel 1.
  std::uint8_t low_frequency_channels = 0;  ///< bit 0 = channel 1.
  double inter_pulse_interval_ms = 8.0;     ///< 1.5 + 0.5·[0, 255] ms.
  double main_interval_ms = 25.0;           ///< 1 + 0.5·[0, 2048] ms.
  bool as_fast_as_possible = false;         ///< channel execution byte.
};
/// InitChannelListMode (§4.3). Intervals round to the 0.5 ms code.
/// kInvalidArgument naming the field if a value is out of range.
api::Result<std::vector<std::uint8_t>> BuildInitChannelListMode(std::uint8_t packet_number,
                                                                const ChannelListInit& init);

/// One active channel's entry in StartChannelListMode (§4.3).
struct ChannelPulse {
  std::uint8_t mode = 0;   ///< 0 single, 1 doublet, 2 triplet.
  int pulse_width_us = 0;  ///< [0, 500].
  int current_ma = 0;      ///< [0, 130].
};
/// StartChannelListMode (§4.3): 4 bytes per active channel in increasing
/// channel order: mode, pulse width MSB, pulse width LSB, current.
/// kInvalidArgument naming the field if a value is out of range or there
/// are more than 8 channels.
api::Result<std::vector<std::uint8_t>> BuildStartChannelListMode(
    std::uint8_t packet_number, std::span<const ChannelPulse> pulses);

/// SinglePulse (§4.4): one pulse on one channel now, outside channel-list
/// mode. Data: channel number (0–7, i.e. channel − 1), pulse width MSB and
/// LSB (µs), current (mA) — the field list of §4.4, with the byte order of
/// the other 16-bit fields (not checked against a device).
/// kInvalidArgument naming the field if a value is out of range.
api::Result<std::vector<std::uint8_t>> BuildSinglePulse(std::uint8_t packet_number, int channel,
                                                        int pulse_width_us, int current_ma);

/// A reply from the device, classified.
struct Reply {
  Command command{};  ///< the §3 number (ack, Init, StimulationError…).
  std::uint8_t packet_number = 0;
  std::int8_t result = 0;  ///< result / error byte (byte 7), 0 if none.
  std::uint8_t extra = 0;  ///< byte 8 where present (e.g. stimulation mode).
};
/// Parses a decoded packet sent by the device. nullopt if the command number
/// is not one the device sends to the PC or the data is too short.
std::optional<Reply> ParseReply(const Packet& packet);

}  // namespace fesbench::server::sciencemode2
