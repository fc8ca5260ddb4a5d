#pragma once

// A seeded simulated leg behind the safety layer, for the protocol engine's
// tests (runner, rapid, tracking, daily check).

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "server/bench/simulated_bench.h"
#include "server/protocols/runner.h"

namespace fesbench::server::protocols::test {

/// A session's values for `vs`: its threshold and max tolerated, the range
/// of motion 15–108° (inside the bench's 10–110° stops).
inline SubjectContext SessionValues(const VirtualSubject& vs) {
  SubjectContext s;
  s.threshold_ma = vs.threshold_ma;
  s.max_tolerated_ma = vs.max_tolerated_ma;
  s.min_angle_deg = 15.0;
  s.max_angle_deg = 108.0;
  return s;
}

/// SessionValues with the inertia known (§7.4.1: from a slow, accurate
/// method; the rapid routine needs one).
inline SubjectContext WithKnownInertia(const VirtualSubject& vs) {
  SubjectContext s = SessionValues(vs);
  s.inertia_kgm2 = vs.truth.passive.inertia_kgm2;
  return s;
}

/// The bench, its safety log and the safe bench over it, for seed `seed`
/// (DrawVirtualSubject) or a given subject.
struct Rig {
  explicit Rig(std::uint64_t seed, SimulatedBenchOptions options = {})
      : Rig(DrawVirtualSubject(seed), std::move(options)) {}
  /// The same for a given subject (another family, changed fidelity).
  explicit Rig(VirtualSubject vs, SimulatedBenchOptions options = {})
      : subject(std::move(vs)),
        bench_owner(SimulatedBench::Create(subject, std::move(options)).value()),
        bench(*bench_owner),
        safe(bench, log.sink()) {}
  VirtualSubject subject;
  std::unique_ptr<SimulatedBench> bench_owner;  // a valid subject: Create succeeds
  SimulatedBench& bench;
  SafetyEventLog log;
  SafeBench safe;
};

/// Runner options without the heartbeat watchdog (no client in these tests).
inline RunnerOptions NoWatchdog() {
  RunnerOptions o;
  o.arm_watchdog = false;
  return o;
}

/// RMS difference over the common length.
inline double Rms(const std::vector<double>& a, const std::vector<double>& b) {
  const std::size_t n = std::min(a.size(), b.size());
  double s = 0.0;
  for (std::size_t i = 0; i < n; ++i) s += (a[i] - b[i]) * (a[i] - b[i]);
  return std::sqrt(s / static_cast<double>(n));
}

}  // namespace fesbench::server::protocols::test
