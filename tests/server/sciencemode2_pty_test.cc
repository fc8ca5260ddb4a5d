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

#include <fcntl.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <termios.h>
#include <unistd.h>

#include <csignal>

namespace fesbench::server::sciencemode2 {
namespace {

using namespace std::chrono_literals;

class Link {
 public:
  explicit Link(const std::string& path) { error_ = port_.Open(path, ScienceMode2Settings()); }
  const api::Status& error() const { return error_; }
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
    ASSERT_TRUE(port_.Write(BuildInitAck(0, 0)).ok());
  }

 private:
  SerialPort port_;
  FrameSplitter splitter_;
  std::vector<std::vector<std::uint8_t>> frames_;
  api::Status error_;
};

ChannelListInit TwoChannels() {
  ChannelListInit init;
  init.active_channels = 0x05;  // channels 1 and 3
  init.main_interval_ms = 25.0;
  return init;
}

TEST(ScienceMode2Pty, InitChannelListStartStopAreAckedAndRecorded) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Link link(emulator.port_path());
  ASSERT_TRUE(link.error().ok()) << link.error().ToString();
  link.Connect();
  ASSERT_TRUE(link.port().Write(*BuildInitChannelListMode(1, TwoChannels())).ok());
  auto ack = link.Expect(Command::kInitChannelListModeAck);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ack->packet_number, 1);  // §2.2: echoed packet number
  EXPECT_EQ(ack->result, 0);
  const ChannelPulse pulses[] = {{0, 300, 40}, {0, 250, 15}};  // 15 mA is 0x0F: stuffed
  ASSERT_TRUE(link.port().Write(*BuildStartChannelListMode(2, pulses)).ok());
  ack = link.Expect(Command::kStartChannelListModeAck);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ack->result, 0);
  ASSERT_TRUE(link.port().Write(BuildStopChannelListMode(3)).ok());
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
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Link link(emulator.port_path());
  ASSERT_TRUE(link.error().ok()) << link.error().ToString();
  link.Connect();
  const ChannelPulse one[] = {{0, 300, 40}};
  ASSERT_TRUE(link.port().Write(*BuildStartChannelListMode(1, one)).ok());
  auto ack = link.Expect(Command::kStartChannelListModeAck);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ResultName(ack->result), "Wrong mode error");
  ASSERT_TRUE(link.port().Write(*BuildInitChannelListMode(2, TwoChannels())).ok());
  ASSERT_TRUE(link.Expect(Command::kInitChannelListModeAck));
  ASSERT_TRUE(link.port().Write(*BuildStartChannelListMode(3, one)).ok());  // 2 active, 1 sent
  ack = link.Expect(Command::kStartChannelListModeAck);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ResultName(ack->result), "Parameter error");
  EXPECT_TRUE(emulator.deliveries().empty());
}

TEST(ScienceMode2Pty, BadChecksumFromThePcIsAckedWithTransferError) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Link link(emulator.port_path());
  ASSERT_TRUE(link.error().ok()) << link.error().ToString();
  link.Connect();
  auto wire = *BuildInitChannelListMode(4, TwoChannels());
  wire[2] ^= 0x01;
  ASSERT_TRUE(link.port().Write(wire).ok());
  const auto ack = link.Expect(Command::kInitChannelListModeAck);
  ASSERT_TRUE(ack);
  EXPECT_EQ(ack->packet_number, 4);
  EXPECT_EQ(ResultName(ack->result), "Transfer error");
}

TEST(ScienceMode2Pty, UnknownCommandIsEchoed) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Link link(emulator.port_path());
  ASSERT_TRUE(link.error().ok()) << link.error().ToString();
  link.Connect();
  const std::uint8_t none[] = {0};
  ASSERT_TRUE(link.port().Write(EncodePacket(5, static_cast<Command>(99), none)).ok());
  const auto reply = link.Expect(Command::kUnknownCommand);
  ASSERT_TRUE(reply);
  EXPECT_EQ(static_cast<std::uint8_t>(reply->result), 99);
}

TEST(ScienceMode2Pty, CorruptRepliesFailTheirChecksum) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  emulator.set_fault(EmulatorFault::kCorruptReplies);
  Link link(emulator.port_path());
  ASSERT_TRUE(link.error().ok()) << link.error().ToString();
  const auto r = link.Next(2000ms);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->error, DecodeError::kChecksum);
}

TEST(ScienceMode2Pty, SilentDeviceAnswersNothing) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Link link(emulator.port_path());
  ASSERT_TRUE(link.error().ok()) << link.error().ToString();
  link.Connect();
  emulator.set_fault(EmulatorFault::kSilent);
  ASSERT_TRUE(link.port().Write(*BuildInitChannelListMode(1, TwoChannels())).ok());
  EXPECT_FALSE(link.Next(300ms));  // MaxResponseTime is 100 ms (§2.3)
}

TEST(ScienceMode2Pty, PulledCableIsAHangUp) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Link link(emulator.port_path());
  ASSERT_TRUE(link.error().ok()) << link.error().ToString();
  link.Connect();
  emulator.Unplug();
  bool gone = false;
  EXPECT_FALSE(link.Next(1000ms, &gone));
  EXPECT_TRUE(gone);
}

TEST(ScienceMode2Pty, DeviceWatchdogStopsStimulationWithoutTraffic) {
  // §2.3: WatchdogTimeout 1200 ms; §5.2: stimulation stopped, Init resent.
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Link link(emulator.port_path());
  ASSERT_TRUE(link.error().ok()) << link.error().ToString();
  link.Connect();
  ASSERT_TRUE(link.port().Write(*BuildInitChannelListMode(1, TwoChannels())).ok());
  ASSERT_TRUE(link.Expect(Command::kInitChannelListModeAck));
  const ChannelPulse pulses[] = {{0, 300, 40}, {0, 300, 40}};
  ASSERT_TRUE(link.port().Write(*BuildStartChannelListMode(2, pulses)).ok());
  ASSERT_TRUE(link.Expect(Command::kStartChannelListModeAck));
  EXPECT_TRUE(link.Expect(Command::kInit, 2500ms)) << "no Init after the watchdog";
  EXPECT_FALSE(emulator.stimulating());
  const auto d = emulator.deliveries();
  ASSERT_FALSE(d.empty());
  EXPECT_TRUE(d.back().stop);
  EXPECT_EQ(d.back().reason, "watchdog");
}

TEST(ScienceMode2Pty, GetStimulationModeIsAnsweredWithTheMode) {
  // §4.2: result 0, then 0 start mode, 1 initialised, 2 running.
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Link link(emulator.port_path());
  ASSERT_TRUE(link.error().ok()) << link.error().ToString();
  link.Connect();
  const auto mode = [&](std::uint8_t number) {
    EXPECT_TRUE(link.port().Write(BuildGetStimulationMode(number)).ok());
    auto reply = link.Expect(Command::kGetStimulationModeAck);
    EXPECT_TRUE(reply);
    EXPECT_EQ(reply ? reply->packet_number : 0, number);
    return reply ? reply->extra : 0xFF;
  };
  EXPECT_EQ(mode(1), 0);
  ASSERT_TRUE(link.port().Write(*BuildInitChannelListMode(2, TwoChannels())).ok());
  ASSERT_TRUE(link.Expect(Command::kInitChannelListModeAck));
  EXPECT_EQ(mode(3), 1);
  const ChannelPulse pulses[] = {{0, 300, 10}, {0, 300, 10}};
  ASSERT_TRUE(link.port().Write(*BuildStartChannelListMode(4, pulses)).ok());
  ASSERT_TRUE(link.Expect(Command::kStartChannelListModeAck));
  EXPECT_EQ(mode(5), 2);
  EXPECT_EQ(StimulationModeName(2), "channel list running");
}

// The line settings each device documents, set and read back (tcgetattr)
// on a real pty: the RehaStim 2's (§2.1 Table 4) and the P24's (the
// ScienceMode4 library's smpt_serial_port_linux.c).
TEST(SerialPortOnAPty, EachDevicesSettingsReadBack) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  SerialPort port;
  ASSERT_TRUE(port.Open(emulator.port_path(), ScienceMode2Settings()).ok());
  const SerialSettings sm2 = port.settings();
  EXPECT_EQ(sm2.baud, 460800);
  // Parity (E) is not kept by a pty: Linux's pty driver clears PARENB, so
  // Open checks it back on real ports only.
  EXPECT_FALSE(sm2.even_parity);
  EXPECT_EQ(sm2.stop_bits, 1);
  EXPECT_FALSE(sm2.rts_cts);
  EXPECT_EQ(ScienceMode2Settings().Describe(), "460800 8E1, no flow control");
  port.Close();
  ASSERT_TRUE(port.Open(emulator.port_path(), ScienceMode4Settings()).ok());
  const SerialSettings sm4 = port.settings();
  EXPECT_EQ(sm4.baud, 3000000);
  EXPECT_FALSE(sm4.even_parity);
  EXPECT_EQ(sm4.stop_bits, 2);
  EXPECT_TRUE(sm4.rts_cts);
  EXPECT_EQ(sm4.Describe(), "3000000 8N2, RTS/CTS");
}

TEST(SerialPortOnAPty, APortAnotherProgramLeftConfiguredOpens) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  {
    // What another program may leave: canonical mode, echo, XON/XOFF, odd
    // parity, 7 bits, 9600 baud, no CLOCAL (the open would wait for carrier).
    const int fd = ::open(emulator.port_path().c_str(), O_RDWR | O_NOCTTY);
    ASSERT_GE(fd, 0);
    termios tio{};
    ASSERT_EQ(::tcgetattr(fd, &tio), 0);
    tio.c_lflag |= ICANON | ECHO;
    tio.c_iflag |= IXON | IXOFF | ICRNL;
    tio.c_cflag = CS7 | PARENB | PARODD | CREAD | HUPCL;
    ::cfsetspeed(&tio, B9600);
    ASSERT_EQ(::tcsetattr(fd, TCSANOW, &tio), 0);
    ::close(fd);
  }
  SerialPort port;
  // Each device's settings over the other's, twice: a second server start
  // on a port the first one configured.
  for (int round = 0; round < 2; ++round) {
    ASSERT_TRUE(port.Open(emulator.port_path(), ScienceMode2Settings()).ok()) << round;
    EXPECT_EQ(port.settings().baud, 460800);
    ASSERT_TRUE(port.Open(emulator.port_path(), ScienceMode4Settings()).ok()) << round;
    EXPECT_EQ(port.settings().baud, 3000000);
  }
  port.Close();
  // And the driver talks through it.
  Link link(emulator.port_path());
  ASSERT_TRUE(link.error().ok()) << link.error().ToString();
  link.Connect();
}

TEST(SerialPortOnAPty, APortHeldByAnotherProcessIsRefusedNamingIt) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  const std::string path = emulator.port_path();
  // util-linux flock(1) holds the same advisory lock the server takes (-o:
  // flock itself, not the command it runs, keeps the port open).
  const pid_t holder = ::fork();
  ASSERT_GE(holder, 0);
  if (holder == 0) {
    ::setpgid(0, 0);  // flock and its command in a group of their own, ended together
    ::execlp("flock", "flock", "-n", "-o", path.c_str(), "sleep", "10", static_cast<char*>(nullptr));
    ::_exit(127);
  }
  bool held = false;
  for (int i = 0; i < 300 && !held; ++i) {  // until the child holds it
    const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK);
    held = fd >= 0 && ::flock(fd, LOCK_EX | LOCK_NB) != 0;
    if (fd >= 0) ::close(fd);
    if (!held) std::this_thread::sleep_for(10ms);
  }
  ASSERT_TRUE(held) << "flock(1) did not take the port";
  SerialPort port;
  const api::Status why = port.Open(path, ScienceMode2Settings());
  ::kill(-holder, SIGTERM);
  ::waitpid(holder, nullptr, 0);
  EXPECT_EQ(why.code(), api::ErrorCode::kUnavailable);
  EXPECT_NE(why.message().find(path + ": in use by process " + std::to_string(holder) + " (flock)"),
            std::string::npos)
      << why.ToString();
  EXPECT_FALSE(port.is_open());
  // Once it is gone, the port opens.
  api::Status after;
  for (int i = 0; i < 200; ++i) {
    after = port.Open(path, ScienceMode2Settings());
    if (after.ok()) break;
    std::this_thread::sleep_for(10ms);
  }
  EXPECT_TRUE(after.ok()) << after.ToString();
  // And this server holds it against a second one (the same lock).
  SerialPort second;
  EXPECT_FALSE(second.Open(path, ScienceMode4Settings()).ok());
}

TEST(ScienceMode2Pty, OpeningAMissingPortNamesIt) {
  SerialPort port;
  const api::Status why = port.Open("/dev/does-not-exist-sm2", ScienceMode2Settings());
  EXPECT_EQ(why.code(), api::ErrorCode::kUnavailable);
  EXPECT_NE(why.message().find("/dev/does-not-exist-sm2"), std::string::npos) << why.ToString();
  EXPECT_FALSE(port.is_open());
}

}  // namespace
}  // namespace fesbench::server::sciencemode2
