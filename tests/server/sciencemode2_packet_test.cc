// ScienceMode2 packet layer against "ScienceMode2 – Description and
// Protocol" v1.24 (2012-12-12). The description has no worked packet dumps,
// so the expected bytes are assembled by hand from its tables: §2.2 Table 5
// (layout), Table 6 (constants), §3 (command numbers), §4.1/§4.3 (fields).
// Checksums were computed with an independent bitwise CRC-8 (poly 0x07)
// whose standard check value is asserted below.

#include "server/bench/sciencemode2_packet.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

namespace fesbench::server::sciencemode2 {
namespace {

using Bytes = std::vector<std::uint8_t>;

TEST(ScienceMode2Crc, StandardCheckValueOfCrc8Poly07) {
  // CRC-8 with x⁸+x²+x+1, init 0, no reflection (§2.2): check("123456789") = 0xF4.
  const std::string s = "123456789";
  const Bytes b(s.begin(), s.end());
  EXPECT_EQ(Crc8(b), 0xF4);
  EXPECT_EQ(Crc8({}), 0x00);
}

TEST(ScienceMode2Stuffing, ReservedBytesAreEscapedWithKey) {
  // §2.2: "this start byte (0xF0) is stuffed to 0x81, 0xA5".
  Bytes out;
  AppendStuffed(out, 0xF0);
  EXPECT_EQ(out, (Bytes{0x81, 0xA5}));
  out.clear();
  AppendStuffed(out, 0x0F);  // stop byte → 0x81, 0x0F^0x55
  AppendStuffed(out, 0x81);  // stuffing byte → 0x81, 0x81^0x55
  AppendStuffed(out, 0x55);  // §2.2: the stuffing key itself is not escaped
  AppendStuffed(out, 0x42);
  EXPECT_EQ(out, (Bytes{0x81, 0x5A, 0x81, 0xD4, 0x55, 0x42}));
}

TEST(ScienceMode2Encode, WatchdogByteForByte) {
  // §4.1 Watchdog: packet number, command 4 (§3.1), no data. Table 5: start,
  // 0x81 + CRC^0x55, 0x81 + length^0x55, body, stop. CRC8{05,04} = 0x5D.
  EXPECT_EQ(BuildWatchdog(5), (Bytes{0xF0, 0x81, 0x08, 0x81, 0x57, 0x05, 0x04, 0x0F}));
}

TEST(ScienceMode2Encode, GetStimulationModeByteForByte) {
  // §4.2 GetStimulationMode: packet number, command 10 (§3.1), no data.
  // CRC8{05,0A} = 0x77.
  EXPECT_EQ(BuildGetStimulationMode(5), (Bytes{0xF0, 0x81, 0x22, 0x81, 0x57, 0x05, 0x0A, 0x0F}));
}

TEST(ScienceMode2Encode, InitChannelListModeByteForByte) {
  // §4.3 InitChannelListMode, command 30: LF factor 0, channels 1+2 (0x03),
  // no LF channels, t2 = 8 ms → (8−1.5)/0.5 = 13, t1 = 25 ms → (25−1)/0.5 =
  // 48 as MSB 0x00, LSB 0x30, fixed interval 0.
  ChannelListInit init;
  init.active_channels = 0x03;
  init.inter_pulse_interval_ms = 8.0;
  init.main_interval_ms = 25.0;
  EXPECT_EQ(*BuildInitChannelListMode(7, init), (Bytes{0xF0, 0x81, 0x84, 0x81, 0x5C, 0x07, 30, 0x00,
                                                       0x03, 0x00, 13, 0x00, 0x30, 0x00, 0x0F}));
}

TEST(ScienceMode2Encode, StartChannelListModeStuffsReservedBytesInsideBody) {
  // §4.3 StartChannelListMode, command 32; one channel: mode 0, width 500 µs
  // (MSB 0x01, LSB 0xF4), current 15 mA = 0x0F (the stop byte → stuffed).
  // Packet number 15 = 0x0F is stuffed too. Length and CRC are of the
  // stuffed body (§2.2): 8 bytes, CRC = 0xA1 (sent as 0xA1^0x55 = 0xF4).
  const ChannelPulse pulse{0, 500, 15};
  EXPECT_EQ(
      *BuildStartChannelListMode(15, std::span(&pulse, 1)),
      (Bytes{0xF0, 0x81, 0xF4, 0x81, 0x5D, 0x81, 0x5A, 0x20, 0x00, 0x01, 0xF4, 0x81, 0x5A, 0x0F}));
}

TEST(ScienceMode2Encode, StopAndInitAck) {
  // §4.3 StopChannelListMode (34) and §4.1 InitAck (2) with result 0.
  const Bytes stop = BuildStopChannelListMode(1);
  ASSERT_EQ(stop.size(), 8u);
  EXPECT_EQ(stop[5], 1);
  EXPECT_EQ(stop[6], 34);
  const Bytes ack = BuildInitAck(0, 0);
  ASSERT_EQ(ack.size(), 9u);
  EXPECT_EQ(ack[6], 2);
  EXPECT_EQ(ack[7], 0);
}

TEST(ScienceMode2Encode, SinglePulse) {
  // §4.4 SinglePulse (36): channel number (channel − 1), pulse width MSB,
  // LSB, current. 300 µs = 0x012C.
  const DecodeResult r = DecodePacket(*BuildSinglePulse(3, 2, 300, 25));
  ASSERT_TRUE(r.packet);
  EXPECT_EQ(r.packet->packet_number, 3);
  EXPECT_EQ(r.packet->command, 36);
  EXPECT_EQ(r.packet->data, (Bytes{0x01, 0x01, 0x2C, 25}));
  EXPECT_FALSE(BuildSinglePulse(0, 9, 300, 10).ok());
  EXPECT_FALSE(BuildSinglePulse(0, 1, 501, 10).ok());
  EXPECT_FALSE(BuildSinglePulse(0, 1, 300, 131).ok());
}

TEST(ScienceMode2Encode, OutOfRangeFieldsAreRefusedNamingTheField) {
  const ChannelPulse too_much{0, 300, 131};
  const auto refused = BuildStartChannelListMode(0, std::span(&too_much, 1));
  ASSERT_FALSE(refused.ok()) << "131 mA accepted";
  EXPECT_EQ(refused.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_NE(refused.status().message().find("current_ma"), std::string::npos)
      << refused.status().message();
  const ChannelPulse too_wide{0, 501, 10};
  EXPECT_FALSE(BuildStartChannelListMode(0, std::span(&too_wide, 1)).ok());
  const ChannelPulse bad_mode{3, 100, 10};
  EXPECT_FALSE(BuildStartChannelListMode(0, std::span(&bad_mode, 1)).ok());
  const std::vector<ChannelPulse> nine(9);
  EXPECT_FALSE(BuildStartChannelListMode(0, nine).ok());
  ChannelListInit init;
  init.main_interval_ms = 1026.0;
  EXPECT_FALSE(BuildInitChannelListMode(0, init).ok());
  init.main_interval_ms = 25.0;
  init.inter_pulse_interval_ms = 1.0;
  EXPECT_FALSE(BuildInitChannelListMode(0, init).ok());
  init.inter_pulse_interval_ms = 8.0;
  init.low_frequency_factor = 8;
  EXPECT_FALSE(BuildInitChannelListMode(0, init).ok());
}

TEST(ScienceMode2Decode, RoundTripsEveryByteValue) {
  Bytes data(256);
  for (int i = 0; i < 256; ++i) data[i] = static_cast<std::uint8_t>(i);
  // Data length is one byte (§2.2), so split into chunks that fit < 61 bytes stuffed.
  for (int start = 0; start < 256; start += 20) {
    const Bytes chunk(data.begin() + start, data.begin() + std::min(start + 20, 256));
    const Bytes wire = EncodePacket(static_cast<std::uint8_t>(start), Command::kSinglePulse, chunk);
    // No reserved byte appears between the start and stop bytes.
    for (std::size_t i = 1; i + 1 < wire.size(); ++i) {
      EXPECT_NE(wire[i], kStartByte);
      EXPECT_NE(wire[i], kStopByte);
    }
    const DecodeResult r = DecodePacket(wire);
    ASSERT_TRUE(r.packet) << DecodeErrorName(*r.error);
    EXPECT_EQ(r.packet->packet_number, start);
    EXPECT_EQ(r.packet->command, 36);
    EXPECT_EQ(r.packet->data, chunk);
  }
}

TEST(ScienceMode2Decode, DetectsChecksumLengthAndFramingErrors) {
  // §5.2: checksum error, data length error, packet frame error.
  Bytes wire = BuildWatchdog(5);
  Bytes bad_crc = wire;
  bad_crc[2] ^= 0x01;
  EXPECT_EQ(DecodePacket(bad_crc).error, DecodeError::kChecksum);
  Bytes bad_len = wire;
  bad_len[4] ^= 0x01;
  EXPECT_EQ(DecodePacket(bad_len).error, DecodeError::kLength);
  Bytes no_stop = wire;
  no_stop.back() = 0x00;
  EXPECT_EQ(DecodePacket(no_stop).error, DecodeError::kFraming);
  EXPECT_EQ(DecodePacket(Bytes{0xF0, 0x0F}).error, DecodeError::kFraming);
  // A stuffing byte followed by a non-constant: 0x81, 0x00 (0x00^0x55 = 0x55).
  Bytes body{0x01, 0x81, 0x00};
  Bytes bad_stuff{0xF0, 0x81, static_cast<std::uint8_t>(Crc8(body) ^ 0x55), 0x81,
                  static_cast<std::uint8_t>(body.size() ^ 0x55)};
  bad_stuff.insert(bad_stuff.end(), body.begin(), body.end());
  bad_stuff.push_back(0x0F);
  EXPECT_EQ(DecodePacket(bad_stuff).error, DecodeError::kBadStuffing);
}

TEST(ScienceMode2Splitter, SplitsStreamAndDropsBytesBeforeASecondStart) {
  FrameSplitter splitter;
  const Bytes a = BuildWatchdog(1);
  const Bytes b = BuildStopChannelListMode(2);
  Bytes stream{0x33, 0xF0, 0x12};  // noise, then a start with no stop (§5.2)
  stream.insert(stream.end(), a.begin(), a.end());
  stream.insert(stream.end(), b.begin(), b.begin() + 3);
  auto frames = splitter.Feed(stream);
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames[0], a);
  frames = splitter.Feed(std::span(b).subspan(3));
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames[0], b);
}

TEST(ScienceMode2Splitter, AStuffedChecksumEqualToADelimiterDoesNotSplitTheFrame) {
  // §2.2: the checksum is always stuffed, so its wire byte is CRC ^ 0x55,
  // which is 0xF0 for Watchdog #196 (CRC 0xA5) and 0x0F for #220 (CRC 0x5A).
  const Bytes a = BuildWatchdog(196);
  const Bytes b = BuildWatchdog(220);
  EXPECT_EQ(a[2], 0xF0);
  EXPECT_EQ(b[2], 0x0F);
  Bytes stream = a;
  stream.insert(stream.end(), b.begin(), b.end());
  FrameSplitter splitter;
  const auto frames = splitter.Feed(stream);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0], a);
  EXPECT_EQ(frames[1], b);
  EXPECT_TRUE(DecodePacket(frames[0]).packet);
  EXPECT_TRUE(DecodePacket(frames[1]).packet);
}

TEST(ScienceMode2Reply, ParsesAcksErrorsAndInit) {
  auto parse = [](Command c, Bytes data) {
    const Bytes wire = EncodePacket(9, c, data);
    return ParseReply(*DecodePacket(wire).packet);
  };
  const auto ack = parse(Command::kStartChannelListModeAck, {0x00});
  ASSERT_TRUE(ack);
  EXPECT_EQ(ack->command, Command::kStartChannelListModeAck);
  EXPECT_EQ(ack->packet_number, 9);
  EXPECT_EQ(ack->result, 0);
  const auto busy = parse(Command::kInitChannelListModeAck, {0xF8});  // −8
  ASSERT_TRUE(busy);
  EXPECT_EQ(busy->result, -8);
  EXPECT_EQ(ResultName(busy->result), "Busy error");
  const auto err = parse(Command::kStimulationError, {0xFE});  // −2 (§4.3)
  ASSERT_TRUE(err);
  EXPECT_EQ(StimulationErrorName(err->result), "Electrode error");
  const auto init = parse(Command::kInit, {0x01});
  ASSERT_TRUE(init);
  EXPECT_EQ(init->result, 1);
  const auto mode = parse(Command::kGetStimulationModeAck, {0x00, 0x02});
  ASSERT_TRUE(mode);
  EXPECT_EQ(mode->extra, 2);                                // §4.2: stimulation started
  EXPECT_FALSE(parse(Command::kStartChannelListMode, {}));  // a PC→device command
  EXPECT_FALSE(parse(Command::kSinglePulseAck, {}));        // missing result byte
}

}  // namespace
}  // namespace fesbench::server::sciencemode2
