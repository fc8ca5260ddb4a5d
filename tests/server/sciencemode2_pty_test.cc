// The ScienceMode2 packet layer and the termios serial port against the
// RehaStim2 emulator over a real pseudo-terminal. Behaviour per
// "ScienceMode2 – Description and Protocol" v1.24: §3.5 (Init from the
// device, InitAck from the PC), §4.3 (channel list mode), §5.2 (transfer
// error ack on a bad checksum; UnknownCommand), §2.3 (WatchdogTimeout).

#include <gtest/gtest.h>

#include <chrono>
#include <optional>
#include <thread>

#include "server/bench/emulator/sciencemode2_emulator.h"
#include "server/bench/sciencemode2_packet.h"
#include "server/bench/serial_port.h"

namespace fesbench::server::sciencemode2 {
namespace {

using namespace std::chrono_literals;

class Link {
 public:
  explicit Link(const std::string& path) { error_ = port_.Open(path); }
  const std::string& error() const { return error_; }
  SerialPort& port() { return port_; }

  /// The next frame, decoded; nullopt on timeout. `gone` is set on hang-up.
  std::optional<DecodeResult> Next(std::chrono::milliseconds timeout, bool* gone = nullptr) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      if (!frames_.empty()) {
        auto f = frames_.front();
        frames_.erase(frames_.begin());
        return DecodePacket(f);
      }
      std::uint8_t buf[256];
      const int n = port_.Read(buf, 20ms);
      if (n < 0) {
        if (gone) *gone = true;
        return std::nullopt;
      }
      for (auto& f : splitter_.Feed(std::span(buf, static_cast<std::size_t>(n)))) {
        frames_.push_back(std::move(f));
      }
    }
    return std::nullopt;
  }

  /// Waits for a reply with this command number, skipping repeated Inits.
  std::optional<Reply> Expect(Command command, std::chrono::milliseconds timeout = 1000ms) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      auto r = Next(timeout);
      if (!r || !r->packet) return std::nullopt;
      auto reply = ParseReply(*r->packet);
      if (reply && reply->command == command) return reply;
    }
    return std::nullopt;
  }

  /// §3.5: wait for the device's Init, answer InitAck 0.
  void Connect() {
    ASSERT_TRUE(Expect(Command::kInit, 2000ms)) << "no Init from the device";
    ASSERT_EQ(port_.Write(BuildInitAck(0, 0)), "");
  }

 private:
  SerialPort port_;
  FrameSplitter splitter_;
  std::vector<std::vector<std::uint8_t>> frames_;
  std::string error_;
};

ChannelListInit TwoChannels() {
  ChannelListInit init;
  init.active_channels = 0x05;  // channels 1 and 3
  init.main_interval_ms = 25.0;
  return init;
}

TEST(ScienceMode2Pty, InitChannelListStartStopAreAckedAndRecorded) {
  Emulator emulator;
  Link link(emulator.port_path());
  ASSERT_EQ(link.error(), "");
  link.Connect();
  ASSERT_EQ(link.port().Write(BuildInitChannelListMode(1, TwoChannels())), "");
  auto ack = link.Expect(Command::kInitChannelListModeAck);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ack->packet_number, 1);  // §2.2: echoed packet number
  EXPECT_EQ(ack->result, 0);
  const ChannelPulse pulses[] = {{0, 300, 40}, {0, 250, 15}};  // 15 mA is 0x0F: stuffed
  ASSERT_EQ(link.port().Write(BuildStartChannelListMode(2, pulses)), "");
  ack = link.Expect(Command::kStartChannelListModeAck);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ack->result, 0);
  ASSERT_EQ(link.port().Write(BuildStopChannelListMode(3)), "");
  ack = link.Expect(Command::kStopChannelListModeAck);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ack->packet_number, 3);
  const auto d = emulator.deliveries();
  ASSERT_EQ(d.size(), 3u);
  EXPECT_EQ(d[0].channel, 1);
  EXPECT_EQ(d[0].current_ma, 40);
  EXPECT_EQ(d[0].pulse_width_us, 300);
  EXPECT_EQ(d[1].channel, 3);
  EXPECT_EQ(d[1].current_ma, 15);
  EXPECT_EQ(d[1].pulse_width_us, 250);
  EXPECT_TRUE(d[2].stop);
  EXPECT_EQ(d[2].reason, "command");
}

TEST(ScienceMode2Pty, WrongChannelCountIsAParameterErrorAndStartBeforeInitAWrongModeError) {
  Emulator emulator;
  Link link(emulator.port_path());
  ASSERT_EQ(link.error(), "");
  link.Connect();
  const ChannelPulse one[] = {{0, 300, 40}};
  ASSERT_EQ(link.port().Write(BuildStartChannelListMode(1, one)), "");
  auto ack = link.Expect(Command::kStartChannelListModeAck);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ResultName(ack->result), "Wrong mode error");
  ASSERT_EQ(link.port().Write(BuildInitChannelListMode(2, TwoChannels())), "");
  ASSERT_TRUE(link.Expect(Command::kInitChannelListModeAck));
  ASSERT_EQ(link.port().Write(BuildStartChannelListMode(3, one)), "");  // 2 active, 1 sent
  ack = link.Expect(Command::kStartChannelListModeAck);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ResultName(ack->result), "Parameter error");
  EXPECT_TRUE(emulator.deliveries().empty());
}

TEST(ScienceMode2Pty, BadChecksumFromThePcIsAckedWithTransferError) {
  Emulator emulator;
  Link link(emulator.port_path());
  ASSERT_EQ(link.error(), "");
  link.Connect();
  auto wire = BuildInitChannelListMode(4, TwoChannels());
  wire[2] ^= 0x01;
  ASSERT_EQ(link.port().Write(wire), "");
  const auto ack = link.Expect(Command::kInitChannelListModeAck);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ack->packet_number, 4);
  EXPECT_EQ(ResultName(ack->result), "Transfer error");
}

TEST(ScienceMode2Pty, UnknownCommandIsEchoed) {
  Emulator emulator;
  Link link(emulator.port_path());
  ASSERT_EQ(link.error(), "");
  link.Connect();
  const std::uint8_t none[] = {0};
  ASSERT_EQ(link.port().Write(EncodePacket(5, static_cast<Command>(99), none)), "");
  const auto reply = link.Expect(Command::kUnknownCommand);
  ASSERT_TRUE(reply);
  EXPECT_EQ(static_cast<std::uint8_t>(reply->result), 99);
}

TEST(ScienceMode2Pty, CorruptRepliesFailTheirChecksum) {
  Emulator emulator;
  emulator.set_fault(EmulatorFault::kCorruptReplies);
  Link link(emulator.port_path());
  ASSERT_EQ(link.error(), "");
  const auto r = link.Next(2000ms);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->error, DecodeError::kChecksum);
}

TEST(ScienceMode2Pty, SilentDeviceAnswersNothing) {
  Emulator emulator;
  Link link(emulator.port_path());
  ASSERT_EQ(link.error(), "");
  link.Connect();
  emulator.set_fault(EmulatorFault::kSilent);
  ASSERT_EQ(link.port().Write(BuildInitChannelListMode(1, TwoChannels())), "");
  EXPECT_FALSE(link.Next(300ms));  // MaxResponseTime is 100 ms (§2.3)
}

TEST(ScienceMode2Pty, PulledCableIsAHangUp) {
  Emulator emulator;
  Link link(emulator.port_path());
  ASSERT_EQ(link.error(), "");
  link.Connect();
  emulator.Unplug();
  bool gone = false;
  EXPECT_FALSE(link.Next(1000ms, &gone));
  EXPECT_TRUE(gone);
}

TEST(ScienceMode2Pty, DeviceWatchdogStopsStimulationWithoutTraffic) {
  // §2.3: WatchdogTimeout 1200 ms; §5.2: stimulation stopped, Init resent.
  Emulator emulator;
  Link link(emulator.port_path());
  ASSERT_EQ(link.error(), "");
  link.Connect();
  ASSERT_EQ(link.port().Write(BuildInitChannelListMode(1, TwoChannels())), "");
  ASSERT_TRUE(link.Expect(Command::kInitChannelListModeAck));
  const ChannelPulse pulses[] = {{0, 300, 40}, {0, 300, 40}};
  ASSERT_EQ(link.port().Write(BuildStartChannelListMode(2, pulses)), "");
  ASSERT_TRUE(link.Expect(Command::kStartChannelListModeAck));
  EXPECT_TRUE(link.Expect(Command::kInit, 2500ms)) << "no Init after the watchdog";
  EXPECT_FALSE(emulator.stimulating());
  const auto d = emulator.deliveries();
  ASSERT_FALSE(d.empty());
  EXPECT_TRUE(d.back().stop);
  EXPECT_EQ(d.back().reason, "watchdog");
}

TEST(ScienceMode2Pty, OpeningAMissingPortNamesIt) {
  SerialPort port;
  const std::string why = port.Open("/dev/does-not-exist-sm2");
  EXPECT_NE(why.find("/dev/does-not-exist-sm2"), std::string::npos) << why;
  EXPECT_FALSE(port.is_open());
}

}  // namespace
}  // namespace fesbench::server::sciencemode2
