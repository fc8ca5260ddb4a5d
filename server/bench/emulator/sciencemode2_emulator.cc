#include "server/bench/emulator/sciencemode2_emulator.h"

#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <bit>
#include <cerrno>
#include <cstring>
#include <utility>

#include "server/bench/emulator/pseudo_terminal.h"
#include "server/bench/sciencemode2_packet.h"

namespace fesbench::server::sciencemode2 {
namespace {

constexpr auto kInitRepetition = std::chrono::milliseconds(500);    // §2.3 Table 7
constexpr auto kWatchdogTimeout = std::chrono::milliseconds(1200);  // §2.3 Table 7
constexpr std::uint8_t kProtocolVersion = 1;

}  // namespace

api::Result<std::unique_ptr<Emulator>> Emulator::Open() {
  api::Result<emulator::PseudoTerminal> pty = emulator::OpenPseudoTerminal();
  if (!pty.ok()) return pty.status();
  return std::unique_ptr<Emulator>(new Emulator(std::move(pty).value()));
}

Emulator::Emulator(emulator::PseudoTerminal pty)
    : master_fd_(pty.master_fd), port_path_(std::move(pty.port_path)) {
  start_ = last_valid_ = std::chrono::steady_clock::now();
  last_init_ = start_ - kInitRepetition;
  thread_ = std::thread([this] { Loop(); });
}

Emulator::~Emulator() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
  if (master_fd_ >= 0) ::close(master_fd_);
}

void Emulator::Unplug() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
  if (master_fd_ >= 0) ::close(master_fd_);
  master_fd_ = -1;
  connected_ = false;
  stimulating_ = false;
}

std::vector<Delivery> Emulator::deliveries() const {
  std::lock_guard lock(mutex_);
  return deliveries_;
}

double Emulator::Now() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void Emulator::Record(Delivery d) {
  d.t_s = Now();
  d.steady_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                    std::chrono::steady_clock::now().time_since_epoch())
                    .count();
  std::lock_guard lock(mutex_);
  deliveries_.push_back(std::move(d));
}

void Emulator::Send(std::uint8_t packet_number, std::uint8_t command,
                    std::vector<std::uint8_t> data) {
  if (fault_ == EmulatorFault::kSilent && connected_) return;
  std::vector<std::uint8_t> wire = EncodePacket(packet_number, static_cast<Command>(command), data);
  if (fault_ == EmulatorFault::kCorruptReplies) wire[2] ^= 0x01;
  std::size_t done = 0;
  while (done < wire.size()) {
    const ssize_t n = ::write(master_fd_, wire.data() + done, wire.size() - done);
    if (n <= 0) return;  // nobody on the other end: as a device would, drop it
    done += static_cast<std::size_t>(n);
  }
}

void Emulator::Loop() {
  FrameSplitter splitter;
  std::uint8_t buffer[256];
  while (running_) {
    const auto now = std::chrono::steady_clock::now();
    if (!connected_ && now - last_init_ >= kInitRepetition) {
      Send(own_packet_number_++, static_cast<std::uint8_t>(Command::kInit), {kProtocolVersion});
      last_init_ = now;
    }
    if (fault_ == EmulatorFault::kReset) {  // a restart: as after power-on (§3.5)
      if (stimulating_) Record({0, 0, 0, 0, true, "reset"});
      stimulating_ = false;
      initialized_ = false;
      connected_ = false;
      last_init_ = now - kInitRepetition;
      fault_ = EmulatorFault::kNone;
    }
    if (fault_ == EmulatorFault::kWrongMode && stimulating_) {
      Record({0, 0, 0, 0, true, "wrong mode"});
      stimulating_ = false;
      initialized_ = false;
    }
    if (connected_ && now - last_valid_ > kWatchdogTimeout) {
      // §5.2 "Data transfer physically broken": stop, reset all modes, send Init.
      if (stimulating_) Record({0, 0, 0, 0, true, "watchdog"});
      stimulating_ = false;
      initialized_ = false;
      connected_ = false;
    }
    pollfd p{master_fd_, POLLIN, 0};
    if (::poll(&p, 1, 5) <= 0 || !(p.revents & POLLIN)) continue;
    const ssize_t n = ::read(master_fd_, buffer, sizeof buffer);
    if (n <= 0) continue;  // slave not open (EIO) or nothing
    for (const auto& frame : splitter.Feed(std::span(buffer, static_cast<std::size_t>(n)))) {
      HandleFrame(frame);
    }
  }
}

void Emulator::HandleFrame(const std::vector<std::uint8_t>& frame) {
  const DecodeResult r = DecodePacket(frame);
  if (!r.packet) {
    // §5.2: checksum or length error → the command's ack with transfer error.
    // The command byte is read as sent (bytes 5–6, unstuffed if needed).
    if (frame.size() >= 8 &&
        (r.error == DecodeError::kChecksum || r.error == DecodeError::kLength)) {
      std::size_t i = 5;
      auto next = [&]() -> std::uint8_t {
        if (frame[i] == kStuffingByte && i + 1 < frame.size()) {
          i += 2;
          return frame[i - 1] ^ kStuffingKey;
        }
        return frame[i++];
      };
      const std::uint8_t number = next();
      const std::uint8_t command = next();
      Send(number, static_cast<std::uint8_t>(command + 1),
           {static_cast<std::uint8_t>(Result::kTransferError)});
    }
    return;
  }
  const Packet& p = *r.packet;
  last_valid_ = std::chrono::steady_clock::now();
  auto ack = [&](Command c, Result result) {
    Send(p.packet_number, static_cast<std::uint8_t>(c), {static_cast<std::uint8_t>(result)});
  };
  switch (static_cast<Command>(p.command)) {
    case Command::kInitAck:
      if (p.data.size() == 1 && p.data[0] == 0) connected_ = true;
      return;
    case Command::kWatchdog:
      return;  // §4.1: no response
    case Command::kGetStimulationMode: {  // §4.2: result 0, then the mode
      const StimulationMode mode = stimulating_ ? StimulationMode::kChannelListRun
                                   : initialized_ ? StimulationMode::kChannelListInit
                                                  : StimulationMode::kStart;
      return Send(p.packet_number, static_cast<std::uint8_t>(Command::kGetStimulationModeAck),
                  {static_cast<std::uint8_t>(Result::kOk), static_cast<std::uint8_t>(mode)});
    }
    case Command::kInitChannelListMode: {
      if (p.data.size() != 7) return ack(Command::kInitChannelListModeAck, Result::kParameterError);
      if (stimulating_) return ack(Command::kInitChannelListModeAck, Result::kWrongModeError);
      const int main_code = (p.data[4] << 8) | p.data[5];
      if (p.data[0] > 7 || p.data[1] == 0 || main_code > 2048 || p.data[6] > 1) {
        return ack(Command::kInitChannelListModeAck, Result::kParameterError);
      }
      active_channels_ = p.data[1];
      initialized_ = true;
      return ack(Command::kInitChannelListModeAck, Result::kOk);
    }
    case Command::kStartChannelListMode: {
      if (!initialized_) return ack(Command::kStartChannelListModeAck, Result::kWrongModeError);
      const int channels = std::popcount(active_channels_);
      if (p.data.size() != static_cast<std::size_t>(4 * channels)) {
        return ack(Command::kStartChannelListModeAck, Result::kParameterError);
      }
      std::vector<Delivery> batch;
      int k = 0;
      for (int ch = 0; ch < kChannelCount; ++ch) {
        if (!(active_channels_ & (1 << ch))) continue;
        const std::uint8_t* e = p.data.data() + 4 * k++;
        const int width = (e[1] << 8) | e[2];
        if (e[0] > 2 || width > kMaxPulseWidthUs || e[3] > kMaxCurrentMa) {
          return ack(Command::kStartChannelListModeAck, Result::kParameterError);
        }
        batch.push_back({0, ch + 1, e[3], width, false, ""});
      }
      for (auto& d : batch) Record(d);
      stimulating_ = true;
      return ack(Command::kStartChannelListModeAck, Result::kOk);
    }
    case Command::kSinglePulse: {
      // §4.4, outside channel-list mode (modes are exclusive here: a single
      // pulse while channel-list mode runs is a wrong-mode error).
      if (p.data.size() != 4) return ack(Command::kSinglePulseAck, Result::kParameterError);
      if (stimulating_) return ack(Command::kSinglePulseAck, Result::kWrongModeError);
      const int width = (p.data[1] << 8) | p.data[2];
      if (p.data[0] >= kChannelCount || width > kMaxPulseWidthUs || p.data[3] > kMaxCurrentMa) {
        return ack(Command::kSinglePulseAck, Result::kParameterError);
      }
      Record({0, p.data[0] + 1, p.data[3], width, false, "single"});
      return ack(Command::kSinglePulseAck, Result::kOk);
    }
    case Command::kStopChannelListMode:
      if (stimulating_) Record({0, 0, 0, 0, true, "command"});
      stimulating_ = false;
      initialized_ = false;
      return ack(Command::kStopChannelListModeAck, Result::kOk);
    default:
      Send(p.packet_number, static_cast<std::uint8_t>(Command::kUnknownCommand), {p.command});
  }
}

}  // namespace fesbench::server::sciencemode2
