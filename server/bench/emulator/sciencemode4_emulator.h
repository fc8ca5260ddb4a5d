#pragma once

/// @file
/// A P24 emulator behind a pseudo-terminal, low level (sciencemode4_packet.h):
/// acknowledges Ll_Init, Ll_Channel_Config (one pulse, recorded) and Ll_Stop;
/// a channel config before Ll_Init gets "not initialised"; a frame failing
/// its checksum or length gets a transfer-error ack of the command it
/// names; points outside the device's ranges a parameter error;
/// Get_Stim_Status is answered with the status (low level initialised or
/// not). Faults for tests: corrupt replies, silence, a reset, a wrong
/// status, a pulled cable.

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
#include "server/bench/sciencemode4_packet.h"

namespace fesbench::server::sciencemode4 {

/// One pulse the device was asked to deliver, or a stop.
struct Delivery {
  double t_s = 0;           ///< seconds since the emulator started.
  int channel = 0;          ///< 1–4; 0 for a stop.
  std::vector<Point> points;
  bool stop = false;        ///< Ll_Stop.
  std::int64_t steady_ns = 0;  ///< when it was read, on the host's monotonic clock.
  /// The first phase's current, mA (0 for a stop).
  double current_ma() const { return points.empty() ? 0.0 : points.front().current_ma; }
};

enum class EmulatorFault {
  kNone,
  kCorruptReplies,
  kSilent,
  kReset,      ///< restarts once: leaves low level (as after power-on), then answers.
  kWrongMode,  ///< leaves low level on its own and says "uninitialised" when asked.
};

class Emulator {
 public:
  /// Opens a pseudo-terminal and answers on it until destroyed; kUnavailable
  /// (emulator::OpenPseudoTerminal) if none opens.
  static api::Result<std::unique_ptr<Emulator>> Open();
  ~Emulator();
  Emulator(const Emulator&) = delete;
  Emulator& operator=(const Emulator&) = delete;

  const std::string& port_path() const { return port_path_; }
  void set_fault(EmulatorFault fault) { fault_ = fault; }
  /// Closes the pty master: the driver sees a hang-up.
  void Unplug();
  std::vector<Delivery> deliveries() const;
  bool initialised() const { return initialised_; }

 private:
  explicit Emulator(emulator::PseudoTerminal pty);

  void Loop();
  void HandleFrame(const std::vector<std::uint8_t>& frame);
  void Send(const std::vector<std::uint8_t>& wire);
  void Record(Delivery d);

  int master_fd_ = -1;
  std::string port_path_;
  std::atomic<EmulatorFault> fault_{EmulatorFault::kNone};
  std::atomic<bool> running_{true};
  std::atomic<bool> initialised_{false};
  std::chrono::steady_clock::time_point start_;
  mutable std::mutex mutex_;
  std::vector<Delivery> deliveries_;
  std::thread thread_;
};

}  // namespace fesbench::server::sciencemode4
