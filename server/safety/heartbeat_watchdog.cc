#include "server/safety/heartbeat_watchdog.h"

namespace fesbench::server {

void HeartbeatWatchdog::Arm() {
  Beat();
  fired_.store(false);
  armed_.store(true);
}

std::optional<double> HeartbeatWatchdog::Check(double timeout_s) {
  if (!armed_.load() || fired_.load()) return std::nullopt;
  const double silent = clock_->MonotonicSeconds() - last_beat_s_.load();
  if (!(silent > timeout_s)) return std::nullopt;
  // One caller trips it: the control loop is the only one that checks, but
  // a second checker must not report (and act on) the same trip twice.
  bool expected = false;
  if (!fired_.compare_exchange_strong(expected, true)) return std::nullopt;
  return silent;
}

}  // namespace fesbench::server
