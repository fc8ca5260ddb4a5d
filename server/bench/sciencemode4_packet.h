#pragma once

/// @file
/// The ScienceMode4 packet layer of the P24 (RehaMove3 family), low level,
/// written from the public ScienceMode4 C library (Hasomed,
/// github.com/ScienceMode/ScienceMode4_c_library, MPL/LGPL; cited by file
/// below as "smpt_…"; no code is taken from it):
///
///   byte 0       start 0xF0                                       (smpt_definitions_internal.h)
///   bytes 1–4    0x81, length MSB ^ 0x55, 0x81, length LSB ^ 0x55 (smpt_insert_header)
///   bytes 5–8    0x81, CRC MSB ^ 0x55, 0x81, CRC LSB ^ 0x55
///   from byte 9  stuffed: packet number << 2 | command bits 9–8, command bits 7–0,
///                then the command's data                          (smpt_insert_cmd_number)
///   last byte    stop 0x0F
///
/// The length counts every byte on the wire, start to stop; the checksum is
/// CRC-16-CCITT (polynomial 0x1021, initial 0, no reflection) over the
/// *stuffed* bytes from byte 9 up to the stop byte (smpt_compute_checksum).
/// Stuffing, start, stop and the stuffing key are ScienceMode2's
/// (0x81 then byte ^ 0x55 for 0xF0, 0x0F, 0x81), so the frame splitter is
/// shared (sciencemode2::FrameSplitter).

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "api/status.h"

namespace fesbench::server::sciencemode4 {

/// Low-level command numbers (smpt_definitions.h, Smpt_Cmd).
enum class Command : std::uint16_t {
  kLlInit = 0,
  kLlInitAck = 1,
  kLlChannelConfig = 2,
  kLlChannelConfigAck = 3,
  kLlStop = 4,
  kLlStopAck = 5,
  kGetStimStatus = 62,     ///< general level (smpt_definitions_data_types.h, Smpt_Cmd)
  kGetStimStatusAck = 63,  ///< result, stim status, high-voltage level
};

/// The stimulation status in Get_Stim_Status_Ack (Smpt_Stim_Status).
enum class StimStatus : std::uint8_t {
  kUninitialized = 0,
  kLlInitialized = 1,
  kMlInitialized = 2,
  kMlRunning = 3,
};
/// "uninitialised", "low level initialised", …, or "status N".
std::string StimStatusName(std::uint8_t status);

/// Result codes of the acks (smpt_definitions.h, Smpt_Result).
enum class Result : std::uint8_t {
  kSuccessful = 0,
  kTransferError = 1,   ///< checksum or length mismatch.
  kParameterError = 2,  ///< a parameter value is wrong or missing.
  kProtocolError = 3,
  kUcStimTimeoutError = 4,
  kNotInitializedError = 7,
  kHvError = 8,
  kElectrodeError = 10,
  kInvalidCmdError = 11,
};
/// "Transfer error (checksum or length mismatch)", …; "result code N" else.
std::string ResultName(std::uint8_t code);

// Device limits of a low-level pulse point (smpt_ll_packet_validity.c,
// smpt_insert_ll_point): current −150…150 mA in 0.5 mA steps, time 0–4095 µs,
// at most 16 points, channels 0–3 (red, blue, black, white), connectors 0–1.
inline constexpr double kMaxCurrentMa = 150.0;
inline constexpr double kCurrentStepMa = 0.5;
inline constexpr int kMaxPointTimeUs = 4095;
inline constexpr int kMaxPoints = 16;
inline constexpr int kChannelCount = 4;

/// CRC-16-CCITT: polynomial 0x1021, initial value 0, no reflection, no final
/// XOR (CRC-16/XMODEM; its check value for "123456789" is 0x31C3).
std::uint16_t Crc16(std::span<const std::uint8_t> bytes);

/// One whole packet on the wire (see the file comment).
std::vector<std::uint8_t> EncodePacket(std::uint8_t packet_number, Command command,
                                       std::span<const std::uint8_t> data);

struct Packet {
  std::uint8_t packet_number = 0;  ///< 0–63.
  std::uint16_t command = 0;       ///< raw, 0–1023.
  std::vector<std::uint8_t> data;
};

enum class DecodeError {
  kFraming,      ///< no start/stop byte or header stuffing where expected, or too short.
  kBadStuffing,  ///< a stuffing byte before the stop byte.
  kLength,       ///< the length field is not the frame's length.
  kChecksum,     ///< CRC mismatch.
};
std::string DecodeErrorName(DecodeError error);

struct DecodeResult {
  std::optional<Packet> packet;
  std::optional<DecodeError> error;
};
/// Decodes one frame from its start byte to its stop byte inclusive.
DecodeResult DecodePacket(std::span<const std::uint8_t> frame);

/// One point of a low-level pulse: `current_ma` held for `time_us`
/// (smpt_insert_ll_point: 12-bit time; current coded as 2·I + 300 in 10 bits).
struct Point {
  int time_us = 0;
  double current_ma = 0.0;
};

/// Ll_Init (smpt_build_ll_init): high-voltage level 0–7 (0: the device's
/// default), no measurement; kInvalidArgument for another level.
api::Result<std::vector<std::uint8_t>> BuildLlInit(std::uint8_t packet_number,
                                                   int high_voltage_level = 0);
/// Ll_Channel_Config (smpt_build_ll_channel_config): one pulse of 1–16
/// points on a channel (0–3) and connector (0–1), stimulation enabled.
/// kInvalidArgument naming the field if a value is out of range.
api::Result<std::vector<std::uint8_t>> BuildLlChannelConfig(std::uint8_t packet_number, int channel,
                                                            int connector,
                                                            std::span<const Point> points);
/// Ll_Stop: leaves low-level mode.
std::vector<std::uint8_t> BuildLlStop(std::uint8_t packet_number);
/// Get_Stim_Status (general level): no data.
std::vector<std::uint8_t> BuildGetStimStatus(std::uint8_t packet_number);

/// The device's side (for the emulator): an ack with its result; a channel
/// config ack also names the channel and connector, without measurement.
std::vector<std::uint8_t> BuildAck(std::uint8_t packet_number, Command ack, Result result);
std::vector<std::uint8_t> BuildLlChannelConfigAck(std::uint8_t packet_number, Result result,
                                                  int channel, int connector);
/// Get_Stim_Status_Ack (insert_get_stim_status_ack): result, stim status,
/// high-voltage level, one byte each.
std::vector<std::uint8_t> BuildGetStimStatusAck(std::uint8_t packet_number, Result result,
                                                StimStatus status, std::uint8_t high_voltage);

/// A decoded Ll_Channel_Config (the emulator's view of it).
struct ChannelConfig {
  bool enable = false;
  int channel = 0;
  int connector = 0;
  std::vector<Point> points;
};
/// nullopt if the data is too short for the points it announces.
std::optional<ChannelConfig> ParseLlChannelConfig(std::span<const std::uint8_t> data);

}  // namespace fesbench::server::sciencemode4
