#pragma once

/// @file
/// Paces bench time against the wall clock (DESIGN.md §6: real time, a
/// factor of it, or as fast as possible). The clock and the sleep are
/// injected so tests run without real sleeping (STYLE.md: hardware and time
/// come through interfaces).

#include <functional>

namespace fesbench::server {

/// A monotonic wall clock and a way to wait on it.
struct PacerClock {
  std::function<double()> now_s;             ///< monotonic seconds.
  std::function<void(double)> sleep_for_s;   ///< blocks about that long (s ≥ 0).
  /// std::chrono::steady_clock and std::this_thread::sleep_for.
  static PacerClock Steady();
};

/// Keeps bench time at `time_scale` × wall time: Pace(t) sleeps until the
/// wall clock has run (t − t₀)/scale since the anchor (t₀, w₀). The anchor is
/// set on the first call and re-set whenever the bench falls more than
/// `max_lag_s` of wall time behind (it does not race to catch up after the
/// caller paused). Scale 0 never sleeps.
class Pacer {
 public:
  /// @param clock empty members default to PacerClock::Steady().
  /// @param time_scale ≥ 0 (negative or non-finite is taken as 0).
  Pacer(PacerClock clock, double time_scale);

  void set_time_scale(double time_scale);
  double time_scale() const { return time_scale_; }
  void Pace(double bench_t_s);

 private:
  PacerClock clock_;
  double time_scale_ = 0.0;
  bool anchored_ = false;
  double wall0_s_ = 0.0;
  double bench0_s_ = 0.0;
  static constexpr double kMaxLagS = 0.05;
};

}  // namespace fesbench::server
