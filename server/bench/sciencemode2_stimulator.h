#pragma once

/// @file
/// A RehaStim2 driven over ScienceMode2 ("ScienceMode2 – Description and
/// Protocol" v1.24): connect (§3.5 Init/InitAck), channel-list mode at the
/// bench's pulse rate on one channel (§4.3), amplitude updates acknowledged
/// within a timeout, watchdog kept alive (§2.3), stop. Any failure — the
/// port gone, a reply that fails its checksum or framing, no reply in time,
/// an error result, a StimulationError from the device — stops stimulation
/// (best effort), latches, and names the reason. Second line of defence: it
/// refuses any amplitude above the device range or the session maximum.
/// Not thread-safe: one control thread calls it.

#include <chrono>
#include <cstdint>
#include <string>

#include "server/bench/sciencemode2_packet.h"
#include "server/bench/serial_port.h"

namespace fesbench::server::sciencemode2 {

struct StimulatorConfig {
  std::string port_path;                             ///< e.g. /dev/ttyUSB0.
  int channel = 1;                                   ///< 1–8 (Table 3).
  double pulse_rate_hz = 33.0;                       ///< main interval 1/rate, 0.5 ms code.
  int pulse_width_us = 300;                          ///< 20–500 µs.
  double session_max_ma = 100.0;                     ///< refused above this (≤ 130).
  std::chrono::milliseconds reply_timeout{200};      ///< MaxResponseTime is 100 ms.
  std::chrono::milliseconds connect_timeout{1500};   ///< Init every 500 ms.
  std::chrono::milliseconds watchdog_interval{500};  ///< < WatchdogTimeout 1200 ms.
};

class Stimulator {
 public:
  explicit Stimulator(StimulatorConfig config);
  ~Stimulator();  ///< stops stimulation if running.

  /// Opens the port, waits for the device's Init, answers InitAck, and sets
  /// channel-list mode. Returns false (and fault() says why) on failure.
  bool Connect();

  /// Sets the channel's current (mA, rounded to the device's 1 mA step) and
  /// waits for the ack. 0 mA keeps channel-list mode with zero current.
  /// Refused without sending if above the device or session limit.
  bool SetAmplitude(double stim_ma);
  /// StopChannelListMode and wait for its ack.
  bool Stop();
  /// Sends a Watchdog if nothing was sent for watchdog_interval; also reads
  /// any spontaneous packet (StimulationError). Call every control period.
  bool KeepAlive();
  /// Stops the device best-effort and latches `reason` (e.g. a bench e-stop).
  void Fault(const std::string& reason);

  bool faulted() const { return !fault_.empty(); }
  const std::string& fault() const { return fault_; }
  /// The amplitude the device last acknowledged, mA (0 after a stop).
  double acknowledged_ma() const { return acknowledged_ma_; }

 private:
  bool Send(const std::vector<std::uint8_t>& wire);
  /// Waits for `command`'s ack with the packet number just sent.
  bool AwaitAck(Command command);
  bool HandleSpontaneous(const Reply& reply);
  std::uint8_t NextPacketNumber() { return packet_number_++; }

  StimulatorConfig config_;
  SerialPort port_;
  FrameSplitter splitter_;
  std::vector<std::vector<std::uint8_t>> frames_;
  std::uint8_t packet_number_ = 0;
  std::uint8_t last_sent_number_ = 0;
  std::chrono::steady_clock::time_point last_send_{};
  bool stimulating_ = false;
  double acknowledged_ma_ = 0.0;
  std::string fault_;
};

}  // namespace fesbench::server::sciencemode2
