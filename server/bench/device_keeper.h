#pragma once

/// @file
/// The thread a stimulator driver keeps beside its device: it calls the
/// driver's duty (ask the device its state, feed its watchdog, read what it
/// sent) every period, run or no run, until the duty fails or the keeper is
/// stopped. Used by the ScienceMode2 and ScienceMode4 drivers.

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>

#include "api/status.h"

namespace fesbench::server {

class DeviceKeeper {
 public:
  DeviceKeeper() = default;
  DeviceKeeper(const DeviceKeeper&) = delete;
  DeviceKeeper& operator=(const DeviceKeeper&) = delete;
  ~DeviceKeeper() { Stop(); }

  /// Calls `duty` every `period` on a thread of its own until it returns a
  /// Status that is not OK (a fault, which the driver has latched: nothing
  /// more to keep) or Stop. Nothing if running.
  void Start(std::chrono::milliseconds period, std::function<api::Status()> duty);
  /// Ends the thread and waits for it; the duty is not called again.
  void Stop();

 private:
  std::mutex mu_;  // guards stop_
  std::condition_variable cv_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace fesbench::server
