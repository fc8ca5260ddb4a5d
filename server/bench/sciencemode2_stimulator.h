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
/// Threading as StimulatorDevice: EmergencyStop, Fault, estopped and fault
/// from any thread (writes to the port are serialised, and no stimulating
/// packet leaves after an e-stop's StopChannelListMode); the rest from one
/// control thread. After Connect a keeper thread calls KeepAlive every
/// 50 ms, run or no run; exchanges with the device (command and ack,
/// keep-alive) take turns under one lock.
///
/// Faults are seen within one status period: every `status_interval`
/// KeepAlive asks the device its mode (GetStimulationMode, §4.2) and waits
/// for the answer, which also feeds the device's watchdog (WatchdogTimeout
/// 1.2 s, §2.3). No answer within reply_timeout, a mode other than the one
/// the driver set (a device that stopped or reset on its own), or an Init
/// from a device already connected (it restarted, §3.5) is a fault.
/// The port is opened with the description's settings (§2.1 Table 4,
/// ScienceMode2Settings) and held exclusively.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

#include "api/status.h"
#include "server/bench/device_keeper.h"
#include "server/bench/sciencemode2_packet.h"
#include "server/bench/sciencemode_frames.h"
#include "server/bench/serial_port.h"
#include "server/bench/stimulator_device.h"

namespace fesbench::server::sciencemode2 {

/// The rate a RehaStim 2 really fires a channel list at when asked for
/// `requested_hz`: its main interval is 1 ms + a multiple of 0.5 ms (§4.3),
/// e.g. 33 Hz → 30.5 ms → 32.787 Hz.
double DevicePulseRateHz(double requested_hz);

struct StimulatorConfig {
  std::string port_path;                             ///< e.g. /dev/ttyUSB0.
  int channel = 1;                                   ///< 1–8 (Table 3).
  double pulse_rate_hz = 33.0;                       ///< main interval 1/rate, 0.5 ms code.
  int pulse_width_us = 300;                          ///< 20–500 µs.
  double session_max_ma = 100.0;                     ///< refused above this (≤ 130).
  std::chrono::milliseconds reply_timeout{200};      ///< MaxResponseTime is 100 ms.
  std::chrono::milliseconds connect_timeout{1500};   ///< Init every 500 ms.
  /// How often the device is asked its mode: status_interval + keeper tick
  /// (50 ms) + reply_timeout bounds the time to notice a silent, stopped or
  /// reset device (450 ms by default).
  std::chrono::milliseconds status_interval{200};
};

class Stimulator final : public StimulatorDevice {
 public:
  explicit Stimulator(StimulatorConfig config);
  ~Stimulator() override;  ///< stops stimulation if running.

  /// Opens the port, waits for the device's Init, answers InitAck, sets
  /// channel-list mode, and starts the keeper thread. Returns the fault on
  /// failure (fault() keeps it).
  api::Status Connect();

  std::string_view name() const override { return "sciencemode2"; }
  double max_current_ma() const override { return kMaxCurrentMa; }
  double current_step_ma() const override { return 1.0; }
  void SetSessionLimit(double max_ma) override { session_max_ma_.store(max_ma); }

  /// Sets the channel's current (mA, rounded down to the device's 1 mA
  /// step, so never above the command) and waits for the ack; initialises
  /// channel-list mode again first after a stop. 0 mA keeps channel-list
  /// mode with zero current. Refused, as a fault, if above the device or
  /// session limit; while e-stopped only 0 mA is accepted (nothing sent).
  api::Status SetAmplitude(double stim_ma) override;
  /// Stops channel-list mode if it is running (and waits for the ack), then
  /// SinglePulse (§4.4) and waits for its ack. Limits as SetAmplitude.
  api::Result<double> SinglePulse(double stim_ma) override;
  double delivered_ma() const override { return acknowledged_ma_.load(); }
  std::chrono::steady_clock::time_point last_command_written() const override {
    return last_command_written_;
  }
  std::optional<double> own_pulse_rate_hz() const override {
    return DevicePulseRateHz(config_.pulse_rate_hz);
  }
  /// StopChannelListMode and wait for its ack.
  api::Status Stop();
  /// Reads any spontaneous packet (StimulationError, a repeated Init) and,
  /// once per status_interval, asks the device its mode and checks the
  /// answer. Call every control period (the keeper thread calls it too).
  api::Status KeepAlive();
  api::Status Service() override { return KeepAlive(); }
  /// Sends StopChannelListMode at once (no wait for its ack) and latches.
  void EmergencyStop() override;
  void ClearEStop() override { estop_.store(false); }
  bool estopped() const override { return estop_.load(); }
  /// Stops the device best-effort and latches `reason` (the first reason
  /// stays); returns the latched fault. Thread-safe.
  api::Status Fault(api::Status reason);

  bool faulted() const { return faulted_.load(); }
  api::Status fault() const override;
  /// The port's line settings as the terminal reports them now (tcgetattr).
  SerialSettings port_settings() const { return port_.settings(); }
  /// The amplitude the device last acknowledged, mA (0 after a stop).
  double acknowledged_ma() const { return acknowledged_ma_.load(); }

 private:
  /// Writes one packet. A stimulating packet (channel-list init or start)
  /// is not written once an e-stop has latched: the check and the write
  /// hold the same lock as EmergencyStop's StopChannelListMode.
  api::Status Send(const std::vector<std::uint8_t>& wire, bool stimulating);
  /// Writes StopChannelListMode without waiting; the caller holds write_mu_.
  void WriteStopLocked();
  /// InitChannelListMode (§4.3) and wait for its ack.
  api::Status InitChannelList();
  /// Waits for `command`'s ack with the packet number just sent; the ack in
  /// `ack` if given.
  api::Status AwaitAck(Command command, Reply* ack = nullptr);
  /// GetStimulationMode and its answer against the mode the driver set.
  api::Status CheckModeLocked();
  api::Status HandleSpontaneous(const Reply& reply);
  api::Status KeepAliveLocked();
  /// The limit check of SetAmplitude and SinglePulse: a fault
  /// (kFailedPrecondition) if stim_ma is outside 0 – min(device, session
  /// maximum).
  api::Status CheckLimit(double stim_ma);
  std::uint8_t NextPacketNumber() { return packet_number_.fetch_add(1); }

  StimulatorConfig config_;
  SerialPort port_;
  FrameReader reader_{port_};
  std::atomic<std::uint8_t> packet_number_{0};
  std::uint8_t last_sent_number_ = 0;
  std::chrono::steady_clock::time_point last_status_{};  // last GetStimulationMode sent
  std::chrono::steady_clock::time_point last_command_written_{};  // written by the control thread
  std::atomic<bool> connected_{false};  // InitAck sent: an Init now is a reset
  std::mutex io_mu_;     // one exchange with the device at a time (reads of port_)
  std::mutex write_mu_;  // serialises writes to port_; orders them after an e-stop
  std::atomic<bool> estop_{false};
  std::atomic<bool> stimulating_{false};
  std::atomic<bool> mode_ready_{false};  // channel-list mode initialised
  std::atomic<double> acknowledged_ma_{0.0};
  std::atomic<double> session_max_ma_;  // from config, then SetSessionLimit
  std::atomic<bool> faulted_{false};
  mutable std::mutex fault_mu_;  // guards fault_
  api::Status fault_;
  DeviceKeeper keeper_;  // last: stopped first
};

}  // namespace fesbench::server::sciencemode2
