#pragma once

/// @file
/// Paces bench time against the wall clock (docs/ARCHITECTURE.md, "The benches": real time, a
/// factor of it, or as fast as possible). The clock and the sleep are
/// injected so tests run without real sleeping (hardware and time come through
/// interfaces, docs/ARCHITECTURE.md).

#include "api/clock.h"

namespace fesbench::server {

/// Keeps bench time at `time_scale` × wall time: Pace(t) sleeps until the
/// wall clock has run (t − t₀)/scale since the anchor (t₀, w₀). The anchor is
/// set on the first call and re-set whenever the bench falls more than
/// `max_lag_s` of wall time behind (it does not race to catch up after the
/// caller paused). Scale 0 never sleeps.
class Pacer {
 public:
  /// @param clock read and slept on (monotonic seconds); must outlive the pacer.
  /// @param time_scale ≥ 0 (negative or non-finite is taken as 0).
  Pacer(api::Clock* clock, double time_scale);

  void set_time_scale(double time_scale);
  double time_scale() const { return time_scale_; }
  void Pace(double bench_t_s);

 private:
  api::Clock* clock_;
  double time_scale_ = 0.0;
  bool anchored_ = false;
  double wall0_s_ = 0.0;
  double bench0_s_ = 0.0;
  static constexpr double kMaxLagS = 0.05;
};

}  // namespace fesbench::server
