#pragma once

/// @file
/// A P24 driven over ScienceMode4, low level (sciencemode4_packet.h):
/// Ll_Init at connect, then one Ll_Channel_Config per pulse — the host
/// paces every pulse (host_paced), so the composed bench sends each pulse of
/// its pulse clock — and Ll_Stop. A pulse is biphasic and charge-balanced:
/// +I for the pulse width, 100 µs at 0, −I for the pulse width (the library's
/// examples' shape), I rounded down to the 0.5 mA step. Any failure — the
/// port gone, a garbled reply, no reply in time, an error result — stops
/// (best effort), latches, and names the reason; it refuses any current
/// above 150 mA or the session maximum. Not verified against a device: the
/// packet layout is the public C library's, the timing a pty's.
/// The port is opened with the library's settings (ScienceMode4Settings:
/// 3 Mbaud, 8N2, RTS/CTS) and held exclusively. Faults are seen within one
/// status period, run or no run: every status_interval Service asks the
/// device its stimulation status (Get_Stim_Status) and waits for the
/// answer; none within reply_timeout, or a status other than the one the
/// driver set (low level initialised, or uninitialised after a stop: a
/// device that reset or left low level on its own) is a fault. A keeper
/// thread calls Service every 50 ms.
/// Threading as StimulatorDevice; exchanges take turns under one lock.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

#include "api/status.h"
#include "server/bench/device_keeper.h"
#include "server/bench/sciencemode2_packet.h"
#include "server/bench/sciencemode4_packet.h"
#include "server/bench/sciencemode_frames.h"
#include "server/bench/serial_port.h"
#include "server/bench/stimulator_device.h"

namespace fesbench::server::sciencemode4 {

struct StimulatorConfig {
  std::string port_path;                         ///< e.g. /dev/ttyUSB0.
  int channel = 1;                               ///< 1–4 (red, blue, black, white).
  int pulse_width_us = 300;                      ///< each phase, 1–4095 µs.
  double session_max_ma = 100.0;                 ///< refused above this (≤ 150).
  std::chrono::milliseconds reply_timeout{200};
  /// How often the device is asked its status (see the file comment).
  std::chrono::milliseconds status_interval{200};
};

class Stimulator final : public StimulatorDevice {
 public:
  explicit Stimulator(StimulatorConfig config);
  ~Stimulator() override;  ///< Ll_Stop if connected.

  /// Opens the port and sends Ll_Init; the fault on failure (fault() keeps
  /// it).
  api::Status Connect();

  std::string_view name() const override { return "sciencemode4"; }
  double max_current_ma() const override { return kMaxCurrentMa; }
  double current_step_ma() const override { return kCurrentStepMa; }
  bool host_paced() const override { return true; }
  void SetSessionLimit(double max_ma) override { session_max_ma_.store(max_ma); }
  /// Checks the limit and keeps the amplitude (rounded down to the step)
  /// for the host's pulses; sends nothing (the device has no pulse train).
  api::Status SetAmplitude(double stim_ma) override;
  /// One biphasic pulse now (Ll_Channel_Config) and its ack.
  api::Result<double> SinglePulse(double stim_ma) override;
  double delivered_ma() const override { return amplitude_ma_.load(); }
  std::chrono::steady_clock::time_point last_command_written() const override {
    return last_command_written_;
  }
  /// Reads what the device sent on its own and, once per status_interval,
  /// checks its status; the fault on a fault.
  api::Status Service() override;
  /// Sends Ll_Stop at once (no wait for its ack) and latches: no pulse is
  /// sent until ClearEStop, which initialises low-level mode again.
  void EmergencyStop() override;
  void ClearEStop() override { estop_.store(false); }
  bool estopped() const override { return estop_.load(); }
  api::Status fault() const override;
  /// The port's line settings as the terminal reports them now (tcgetattr).
  SerialSettings port_settings() const { return port_.settings(); }
  /// Stops the device best-effort and latches `reason` (the first reason
  /// stays); returns the latched fault. Thread-safe.
  api::Status Fault(api::Status reason);
  bool faulted() const { return faulted_.load(); }

 private:
  api::Status Send(const std::vector<std::uint8_t>& wire, bool stimulating);
  /// Waits for `ack` with the packet number just sent; its result must be 0.
  /// The ack's data in `data` if given.
  api::Status AwaitAck(Command ack, std::vector<std::uint8_t>* data = nullptr);
  /// Get_Stim_Status and its answer against the status the driver set.
  api::Status CheckStatusLocked();
  api::Status CheckLimit(double stim_ma);
  api::Status InitLowLevel();
  std::uint8_t NextPacketNumber() { return packet_number_.fetch_add(1) & 0x3F; }

  StimulatorConfig config_;
  SerialPort port_;
  FrameReader reader_{port_};  // ScienceMode2's delimiters and stuffing
  std::atomic<std::uint8_t> packet_number_{0};
  std::uint8_t last_sent_number_ = 0;
  std::mutex io_mu_;     // one exchange with the device at a time
  std::mutex write_mu_;  // serialises writes; orders them after an e-stop
  std::atomic<bool> estop_{false};
  std::atomic<bool> initialised_{false};
  std::atomic<double> amplitude_ma_{0.0};
  std::atomic<double> session_max_ma_;
  std::atomic<bool> faulted_{false};
  mutable std::mutex fault_mu_;  // guards fault_
  api::Status fault_;
  std::chrono::steady_clock::time_point last_status_{};  // under io_mu_
  std::chrono::steady_clock::time_point last_command_written_{};  // written by the control thread
  DeviceKeeper keeper_;  // last: stopped first
};

}  // namespace fesbench::server::sciencemode4
