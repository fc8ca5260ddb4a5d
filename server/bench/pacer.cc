#include "server/bench/pacer.h"

#include <cmath>

namespace fesbench::server {

Pacer::Pacer(api::Clock* clock, double time_scale)
    : clock_(clock != nullptr ? clock : api::Clock::Real()) {
  set_time_scale(time_scale);
}

void Pacer::set_time_scale(double time_scale) {
  time_scale_ = (std::isfinite(time_scale) && time_scale > 0.0) ? time_scale : 0.0;
  anchored_ = false;
}

void Pacer::Pace(double bench_t_s) {
  if (time_scale_ <= 0.0) return;
  const double now = clock_->MonotonicSeconds();
  if (!anchored_) {
    anchored_ = true;
    wall0_s_ = now;
    bench0_s_ = bench_t_s;
    return;
  }
  const double target = wall0_s_ + (bench_t_s - bench0_s_) / time_scale_;
  if (now > target + kMaxLagS) {
    wall0_s_ = now;
    bench0_s_ = bench_t_s;
    return;
  }
  if (target > now) clock_->SleepFor(target - now);
}

}  // namespace fesbench::server
