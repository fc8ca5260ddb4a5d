#pragma once

/// @file
/// The runs of this process (docs/ARCHITECTURE.md, "Runs"): the one on the
/// bench and the last finished ones, shared by RunService (commands and
/// views) and RunRecorder (what a run produces, stored). Not for other users.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "api/run.h"
#include "server/protocols/plan.h"
#include "server/protocols/protocol.h"
#include "server/protocols/runner.h"
#include "server/services/actor.h"

namespace fesbench::server::services {

/// "runs/{id}", the audit target of a run.
inline std::string RunTarget(std::int64_t run_id) { return "runs/" + std::to_string(run_id); }

/// A number as the audit log and messages show it.
inline std::string FormatNumber(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

/// A run started by this process.
struct LiveRun {
  // Fixed at start.
  std::int64_t run_id = 0;
  std::int64_t subject_id = 0;
  std::int64_t leg_id = 0;
  Actor actor;
  protocols::BenchMode mode = protocols::BenchMode::kLocked;
  std::optional<std::int64_t> prior_parameter_set_id;
  // The recorder's thread only: the last state stored (the error transition
  // starts there).
  protocols::RunState stored_state = protocols::RunState::kQueued;
  // Read and written only inside LiveRuns::Locked.
  api::RunView view;
  std::vector<std::optional<std::int64_t>> trial_ids;  // stored id by trial index
  bool final = false;  // everything the run produced is stored
  /// Handed to the BenchOwner: its end waits for the bench to be released.
  std::atomic<bool> on_bench{false};
  // The run's thread only.
  std::uint64_t next_sample = 0;
};

/// The current run and the last finished ones, under one mutex.
class LiveRuns {
 public:
  /// @param finished_kept finished runs kept in memory besides the current one.
  explicit LiveRuns(std::size_t finished_kept) : finished_kept_(finished_kept) {}

  /// Adds `run` as the current run.
  void Add(std::shared_ptr<LiveRun> run);
  /// The run with this id, or nullptr when it is not (or no longer) held.
  std::shared_ptr<LiveRun> Find(std::int64_t run_id) const;
  /// The current run (the last one added), or nullptr.
  std::shared_ptr<LiveRun> Current() const;

  /// fn() with the lock held: LiveRun::view, trial_ids and final are read
  /// and written only in here. fn must not call back into LiveRuns.
  template <class Fn>
  decltype(auto) Locked(Fn&& fn) const {
    std::lock_guard lock(mu_);
    return fn();
  }
  /// Blocks until `run` is final or `timeout` passes; its view then.
  api::RunView WaitFinal(const LiveRun& run, std::chrono::milliseconds timeout) const;
  /// fn(run.view) with the lock held, then marks the run final, wakes
  /// WaitFinal and forgets the oldest finished runs beyond finished_kept.
  void Finalise(LiveRun& run, const std::function<void(api::RunView&)>& fn);

 private:
  const std::size_t finished_kept_;
  mutable std::mutex mu_;
  mutable std::condition_variable final_cv_;
  std::map<std::int64_t, std::shared_ptr<LiveRun>> runs_;
  std::int64_t current_run_id_ = 0;
};

}  // namespace fesbench::server::services
