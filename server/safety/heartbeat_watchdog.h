#pragma once

/// @file
/// The heartbeat watchdog (docs/SAFETY.md, "Heartbeat watchdog"): while a
/// run is going, its controlling client must beat at least once per timeout;
/// a client silent for longer trips the watchdog, and SafeBench, which owns
/// it and asks it at every control period, stops stimulation and the motor.
///
/// Client liveness is a wall-clock matter even when the simulated bench runs
/// faster than real time, so the watchdog reads its own clock, never the
/// bench's. Thread-safe: Beat comes from a request thread, Check from the
/// control loop.

#include <atomic>
#include <optional>

#include "api/clock.h"

namespace fesbench::server {

class HeartbeatWatchdog {
 public:
  /// @param clock must outlive the watchdog.
  explicit HeartbeatWatchdog(api::Clock* clock) : clock_(clock) {}

  /// Starts watching now (counts as a beat) and clears a previous trip.
  void Arm();
  /// Stops watching; a trip stays visible in fired() until the next Arm.
  void Disarm() { armed_.store(false); }
  /// A beat of the controlling client, now.
  void Beat() { last_beat_s_.store(clock_->MonotonicSeconds()); }

  /// The seconds the client has been silent, once, when this call trips
  /// the watchdog: armed, not yet tripped, and silent for more than
  /// `timeout_s`. std::nullopt otherwise (also on every later call).
  std::optional<double> Check(double timeout_s);
  /// True once the watchdog tripped since it was last armed.
  bool fired() const { return fired_.load(); }

 private:
  api::Clock* clock_;
  std::atomic<bool> armed_{false};
  std::atomic<bool> fired_{false};
  std::atomic<double> last_beat_s_{0.0};
};

}  // namespace fesbench::server
