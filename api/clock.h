#pragma once

/// @file
/// The one clock interface (LevelDB's `Env` idea): everything that
/// reads the time or waits takes an api::Clock*, so a test runs a watchdog,
/// a pacer, a rate limit or a time stamp on time it controls, and the
/// server runs them all on Clock::Real().
///
///   monotonic seconds: durations, pacing, heartbeats, rate limits;
///   UTC: the time stamps storage writes (*_utc columns);
///   SleepFor: the pacer's wait, in the same clock's seconds.

#include <chrono>

namespace fesbench::api {

/// A point in time, UTC, microsecond resolution.
using UtcTime = std::chrono::sys_time<std::chrono::microseconds>;

class Clock {
 public:
  virtual ~Clock() = default;

  /// Seconds from an arbitrary origin; never decreases.
  virtual double MonotonicSeconds() = 0;
  /// The wall-clock time in UTC.
  virtual UtcTime UtcNow() = 0;
  /// Blocks about `seconds` of MonotonicSeconds (≤ 0: returns at once).
  virtual void SleepFor(double seconds) = 0;

  /// The process's clock: std::chrono::steady_clock, system_clock (truncated
  /// to microseconds) and std::this_thread::sleep_for. Never null; it is
  /// never destroyed and may be used from any thread.
  static Clock* Real();
};

}  // namespace fesbench::api
