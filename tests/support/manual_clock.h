#pragma once

// Clocks for tests (api/clock.h): time moves only when the test moves it.

#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <utility>

#include "api/clock.h"

namespace fesbench::testing {

/// Monotonic time set by hand; SleepFor advances it instead of sleeping;
/// UTC is 2026-01-01T00:00:00Z plus the monotonic time.
class ManualClock : public api::Clock {
 public:
  explicit ManualClock(double start_s = 0.0) : now_s_(start_s) {}

  double MonotonicSeconds() override { return now_s_.load(); }
  api::UtcTime UtcNow() override {
    return std::chrono::sys_days{std::chrono::year{2026} / 1 / 1} +
           std::chrono::microseconds(std::llround(now_s_.load() * 1e6));
  }
  void SleepFor(double seconds) override {
    if (seconds > 0.0) Advance(seconds);
  }

  void Set(double seconds) { now_s_.store(seconds); }
  void Advance(double seconds) {
    double now = now_s_.load();
    while (!now_s_.compare_exchange_weak(now, now + seconds)) {
    }
  }

 private:
  std::atomic<double> now_s_;
};

/// Monotonic time read from elsewhere (a bench's own time, so a watchdog
/// counts bench seconds at time scale 0); SleepFor does nothing.
class ReadingClock : public ManualClock {
 public:
  explicit ReadingClock(std::function<double()> read) : read_(std::move(read)) {}
  double MonotonicSeconds() override { return read_(); }
  void SleepFor(double) override {}

 private:
  std::function<double()> read_;
};

}  // namespace fesbench::testing
