#pragma once

/// @file
/// What the server does when its bench lock changes (docs/SAFETY.md, "One
/// server per bench"; storage/bench_lock.h reports the changes):
/// - lost: RunService::LoseBench at once — stimulation stops, the e-stop is
///   latched and stored, new runs (and clearing the e-stop) are refused
///   naming the lost lock — while storage tries to take the lock back;
/// - taken back: runs may start again once a person clears the e-stop;
/// - held by another server: `end_serving` (the server stops serving and
///   exits non-zero; stimulation stopped already when the lock was lost).

#include <functional>
#include <string>
#include <string_view>

#include "server/services/run_service.h"
#include "storage/bench_lock.h"
#include "storage/database.h"

namespace fesbench::server::services {

class BenchLockGuard {
 public:
  /// Listens to `db`'s bench lock until destroyed; `db` and `runs` must
  /// outlive it. `end_serving(why)` and `log(line)` run on the lock's watcher
  /// thread (or on this one, when the lock is lost already).
  BenchLockGuard(storage::Database& db, RunService& runs,
                 std::function<void(const std::string& why)> end_serving,
                 std::function<void(std::string_view line)> log);
  /// Stops listening; when it returns, no thread is inside OnChange.
  ~BenchLockGuard();
  BenchLockGuard(const BenchLockGuard&) = delete;
  BenchLockGuard& operator=(const BenchLockGuard&) = delete;

  /// The refusal RunService answers while the lock is lost.
  static std::string RefusalFor(const storage::BenchLockEvent& event);

 private:
  void OnChange(const storage::BenchLockEvent& event);

  storage::Database& db_;
  RunService& runs_;
  std::function<void(const std::string&)> end_serving_;
  std::function<void(std::string_view)> log_;
};

}  // namespace fesbench::server::services
