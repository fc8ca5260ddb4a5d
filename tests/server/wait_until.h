#pragma once

// Timing of what a test waits for (the stimulator drivers' fault detection).

#include <chrono>
#include <functional>
#include <thread>

namespace fesbench::server::test {

/// Polls `done` every millisecond until it holds or `limit` passes; the
/// milliseconds that took (≥ limit if it never held).
inline double MsUntil(const std::function<bool()>& done,
                      std::chrono::milliseconds limit = std::chrono::seconds(3)) {
  const auto t0 = std::chrono::steady_clock::now();
  while (!done() && std::chrono::steady_clock::now() - t0 < limit) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace fesbench::server::test
