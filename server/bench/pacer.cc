#include "server/bench/pacer.h"

#include <chrono>
#include <cmath>
#include <thread>

namespace fesbench::server {

PacerClock PacerClock::Steady() {
  PacerClock c;
  c.now_s = [] {
    using namespace std::chrono;
    return duration<double>(steady_clock::now().time_since_epoch()).count();
  };
  c.sleep_for_s = [](double s) {
    if (s > 0.0) std::this_thread::sleep_for(std::chrono::duration<double>(s));
  };
  return c;
}

Pacer::Pacer(PacerClock clock, double time_scale) : clock_(std::move(clock)) {
  const PacerClock steady = PacerClock::Steady();
  if (!clock_.now_s) clock_.now_s = steady.now_s;
  if (!clock_.sleep_for_s) clock_.sleep_for_s = steady.sleep_for_s;
  set_time_scale(time_scale);
}

void Pacer::set_time_scale(double time_scale) {
  time_scale_ = (std::isfinite(time_scale) && time_scale > 0.0) ? time_scale : 0.0;
  anchored_ = false;
}

void Pacer::Pace(double bench_t_s) {
  if (time_scale_ <= 0.0) return;
  const double now = clock_.now_s();
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
  if (target > now) clock_.sleep_for_s(target - now);
}

}  // namespace fesbench::server
