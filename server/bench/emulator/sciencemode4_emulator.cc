#include "server/bench/emulator/sciencemode4_emulator.h"

#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <utility>

#include "server/bench/emulator/pseudo_terminal.h"
#include "server/bench/sciencemode2_packet.h"

namespace fesbench::server::sciencemode4 {

api::Result<std::unique_ptr<Emulator>> Emulator::Open() {
  api::Result<emulator::PseudoTerminal> pty = emulator::OpenPseudoTerminal();
  if (!pty.ok()) return pty.status();
  return std::unique_ptr<Emulator>(new Emulator(std::move(pty).value()));
}

Emulator::Emulator(emulator::PseudoTerminal pty)
    : master_fd_(pty.master_fd), port_path_(std::move(pty.port_path)) {
  start_ = std::chrono::steady_clock::now();
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
  initialised_ = false;
}

std::vector<Delivery> Emulator::deliveries() const {
  std::lock_guard lock(mutex_);
  return deliveries_;
}

void Emulator::Record(Delivery d) {
  d.t_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  d.steady_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                    std::chrono::steady_clock::now().time_since_epoch())
                    .count();
  std::lock_guard lock(mutex_);
  deliveries_.push_back(std::move(d));
}

void Emulator::Send(const std::vector<std::uint8_t>& wire_in) {
  if (fault_ == EmulatorFault::kSilent) return;
  std::vector<std::uint8_t> wire = wire_in;
  if (fault_ == EmulatorFault::kCorruptReplies) wire[6] ^= 0x01;  // the CRC's high byte
  std::size_t done = 0;
  while (done < wire.size()) {
    const ssize_t n = ::write(master_fd_, wire.data() + done, wire.size() - done);
    if (n <= 0) return;  // nobody on the other end
    done += static_cast<std::size_t>(n);
  }
}

void Emulator::Loop() {
  sciencemode2::FrameSplitter splitter;  // the same delimiters and stuffing
  std::uint8_t buffer[1024];
  while (running_) {
    if (fault_ == EmulatorFault::kReset) {
      if (initialised_) Record({0, 0, {}, true});
      initialised_ = false;
      fault_ = EmulatorFault::kNone;
    }
    if (fault_ == EmulatorFault::kWrongMode && initialised_) {
      Record({0, 0, {}, true});
      initialised_ = false;
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
    // A transfer error: the ack of the command the frame names (byte 9–10,
    // unstuffed if needed), when it can be read.
    if (frame.size() >= 13 && (r.error == DecodeError::kChecksum || r.error == DecodeError::kLength)) {
      std::size_t i = 9;
      auto next = [&]() -> std::uint8_t {
        if (frame[i] == 0x81 && i + 1 < frame.size()) {
          i += 2;
          return frame[i - 1] ^ 0x55;
        }
        return frame[i++];
      };
      const std::uint8_t first = next();
      const std::uint8_t second = next();
      const auto command = static_cast<std::uint16_t>(((first & 0x03) << 8) | second);
      if (command <= static_cast<std::uint16_t>(Command::kLlStop) && command % 2 == 0) {
        Send(BuildAck(static_cast<std::uint8_t>(first >> 2), static_cast<Command>(command + 1),
                      Result::kTransferError));
      }
    }
    return;
  }
  const Packet& p = *r.packet;
  switch (static_cast<Command>(p.command)) {
    case Command::kLlInit:
      initialised_ = true;
      return Send(BuildAck(p.packet_number, Command::kLlInitAck, Result::kSuccessful));
    case Command::kLlChannelConfig: {
      const auto config = ParseLlChannelConfig(p.data);
      if (!config) {
        return Send(BuildLlChannelConfigAck(p.packet_number, Result::kParameterError, 0, 0));
      }
      if (!initialised_) {
        return Send(BuildLlChannelConfigAck(p.packet_number, Result::kNotInitializedError,
                                            config->channel, config->connector));
      }
      for (const Point& pt : config->points) {
        if (std::abs(pt.current_ma) > kMaxCurrentMa) {
          return Send(BuildLlChannelConfigAck(p.packet_number, Result::kParameterError,
                                              config->channel, config->connector));
        }
      }
      if (config->enable) Record({0, config->channel + 1, config->points, false});
      return Send(BuildLlChannelConfigAck(p.packet_number, Result::kSuccessful, config->channel,
                                          config->connector));
    }
    case Command::kGetStimStatus:
      return Send(BuildGetStimStatusAck(
          p.packet_number, Result::kSuccessful,
          initialised_ ? StimStatus::kLlInitialized : StimStatus::kUninitialized, 0));
    case Command::kLlStop:
      initialised_ = false;
      Record({0, 0, {}, true});
      return Send(BuildAck(p.packet_number, Command::kLlStopAck, Result::kSuccessful));
    default:
      return Send(BuildAck(p.packet_number, static_cast<Command>(p.command + 1),
                           Result::kInvalidCmdError));
  }
}

}  // namespace fesbench::server::sciencemode4
