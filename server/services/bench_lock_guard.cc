#include "server/services/bench_lock_guard.h"

#include <utility>

namespace fesbench::server::services {

BenchLockGuard::BenchLockGuard(storage::Database& db, RunService& runs,
                               std::function<void(const std::string&)> end_serving,
                               std::function<void(std::string_view)> log)
    : db_(db), runs_(runs), end_serving_(std::move(end_serving)), log_(std::move(log)) {
  db_.SetBenchLockListener([this](const storage::BenchLockEvent& event) { OnChange(event); });
}

BenchLockGuard::~BenchLockGuard() { db_.SetBenchLockListener({}); }

std::string BenchLockGuard::RefusalFor(const storage::BenchLockEvent& event) {
  return "this server lost its lock on bench '" + event.bench_id + "' (" + event.detail +
         "): no run starts until it holds the bench again";
}

void BenchLockGuard::OnChange(const storage::BenchLockEvent& event) {
  const std::string bench = "bench '" + event.bench_id + "'";
  switch (event.state) {
    case storage::BenchLockState::kLost:
      runs_.LoseBench(RefusalFor(event));  // stimulation 0 and the latch first
      if (log_) {
        log_("lost the lock on " + bench + " (" + event.detail +
             "): stimulation stopped, e-stop latched, runs refused; taking it back");
      }
      return;
    case storage::BenchLockState::kHeld:
      runs_.RegainBench();
      if (log_) {
        log_("holds " + bench + " again (" + event.detail +
             "); the e-stop stays latched until a person clears it");
      }
      return;
    case storage::BenchLockState::kHeldElsewhere:
      // Normally after kLost; on its own too, the bench is stopped first.
      runs_.LoseBench(RefusalFor(event));
      if (log_) log_(event.detail + ": stimulation stopped; this server stops serving " + bench);
      if (end_serving_) end_serving_(event.detail);
      return;
  }
}

}  // namespace fesbench::server::services
