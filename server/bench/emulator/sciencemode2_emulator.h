#pragma once

/// @file
/// A RehaStim2 emulator behind a pseudo-terminal, answering per
/// "ScienceMode2 – Description and Protocol" v1.24: it sends Init every
/// InitRepetitionTime (§2.3, §3.5) until InitAck, acknowledges
/// InitChannelListMode / StartChannelListMode / StopChannelListMode (§4.3)
/// and SinglePulse outside channel-list mode (§4.4),
/// answers a bad checksum or length with the command's ack carrying the
/// transfer error (§5.2), sends UnknownCommand for unknown numbers (§4.1),
/// and stops stimulation when no valid packet arrives within
/// WatchdogTimeout (§2.3, §5.2); answers GetStimulationMode with its mode
/// (§4.2: 0 start, 1 channel list initialised, 2 running). It records every
/// delivery it was asked for. Faults for tests: corrupt replies, silence, a
/// reset, a wrong mode, a pulled cable.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "api/status.h"
#include "server/bench/emulator/pseudo_terminal.h"

namespace fesbench::server::sciencemode2 {

/// One thing the device was asked to deliver (or stop).
struct Delivery {
  double t_s = 0;   ///< seconds since the emulator started.
  int channel = 0;  ///< 1–8; 0 for a stop record.
  int current_ma = 0;
  int pulse_width_us = 0;
  bool stop = false;   ///< StopChannelListMode, or the watchdog stopping.
  std::string reason;  ///< for stops: "command", "watchdog", "reset" or "wrong mode";
                       ///< "single" for a SinglePulse.
  std::int64_t steady_ns = 0;  ///< when it was read, on the host's monotonic clock.
};

enum class EmulatorFault {
  kNone,
  kCorruptReplies,  ///< every reply's checksum byte is flipped.
  kSilent,          ///< reads everything, answers nothing (after InitAck).
  kReset,           ///< restarts once: stops, forgets InitAck, sends Init again (§3.5).
  kWrongMode,       ///< stops stimulating on its own and says start mode when asked.
};

class Emulator {
 public:
  /// Opens a pseudo-terminal and answers on it until destroyed; kUnavailable
  /// (emulator::OpenPseudoTerminal) if none opens.
  static api::Result<std::unique_ptr<Emulator>> Open();
  ~Emulator();
  Emulator(const Emulator&) = delete;
  Emulator& operator=(const Emulator&) = delete;

  /// The slave side's path (/dev/pts/N) for the driver to open.
  const std::string& port_path() const { return port_path_; }

  void set_fault(EmulatorFault fault) { fault_ = fault; }
  /// Closes the pty master: the driver sees a hang-up (a pulled cable).
  void Unplug();

  std::vector<Delivery> deliveries() const;
  bool connected() const { return connected_; }
  bool stimulating() const { return stimulating_; }

 private:
  explicit Emulator(emulator::PseudoTerminal pty);

  void Loop();
  void HandleFrame(const std::vector<std::uint8_t>& frame);
  void Send(std::uint8_t packet_number, std::uint8_t command, std::vector<std::uint8_t> data);
  void Record(Delivery d);
  double Now() const;

  int master_fd_ = -1;
  std::string port_path_;
  std::atomic<EmulatorFault> fault_{EmulatorFault::kNone};
  std::atomic<bool> running_{true};
  std::atomic<bool> connected_{false};
  std::atomic<bool> stimulating_{false};
  std::uint8_t active_channels_ = 0;
  bool initialized_ = false;
  std::uint8_t own_packet_number_ = 0;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_valid_;
  std::chrono::steady_clock::time_point last_init_;
  mutable std::mutex mutex_;
  std::vector<Delivery> deliveries_;
  std::thread thread_;
};

}  // namespace fesbench::server::sciencemode2
