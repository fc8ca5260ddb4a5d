#pragma once

/// @file
/// The recorder (docs/ARCHITECTURE.md, "Runs"): everything a run produces
/// goes to storage on the recorder's own thread, in the order it happened,
/// so that the control loop never waits for the database.
///
/// The runner's observer (Observe) runs on the run's thread: it only
/// updates the live view, publishes to the hub and queues storage work. The
/// recorder then stores each state event and each finished trial, and at
/// the end the run's one outcome (protocols::ConcludeRun) with the set it
/// made (provenance: the stored trials it was fitted to) or the session
/// revision it wrote, the terminal state (through the run transitions) and
/// an audit row, all in one transaction. The live view turns final only
/// once all of that is stored and the bench is free again. Thread-safe.

#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>

#include "server/protocols/bench_owner.h"
#include "server/protocols/runner.h"
#include "server/services/live_runs.h"
#include "server/services/sample_hub.h"
#include "storage/database.h"

namespace fesbench::server::services {

class RunRecorder {
 public:
  using Log = std::function<void(std::string_view)>;

  /// @param db, hub, runs and owner must outlive the recorder; `log` takes
  ///   what could not be stored.
  RunRecorder(storage::Database& db, SampleHub& hub, LiveRuns& runs, protocols::BenchOwner& owner,
              Log log);
  /// Stop().
  ~RunRecorder();
  RunRecorder(const RunRecorder&) = delete;
  RunRecorder& operator=(const RunRecorder&) = delete;

  /// The runner's observer of `run`, feeding this recorder.
  std::shared_ptr<protocols::RunObserver> Observe(std::shared_ptr<LiveRun> run);
  /// A run the bench refused at the last moment: failed from its stored
  /// state (queued).
  void Refused(std::shared_ptr<LiveRun> run, std::string reason);
  /// Stores everything queued, then stops the thread. Idempotent.
  void Stop();

 private:
  class Observer;
  struct FinishRecord;

  void Enqueue(std::function<void()> task);
  void Loop();
  void RecordState(LiveRun& run, protocols::RunState state, const std::string& reason);
  void RecordTrial(LiveRun& run, const protocols::RecordedTrial& trial);
  void RecordFinish(LiveRun& run, const protocols::RunResult& result);
  // The end of a run (ConcludeRun's outcome, or a refusal): the set and the
  // session limits it stores, the one write transaction (with fallbacks),
  // the final view and its event.
  void Finish(LiveRun& run, FinishRecord& f);
  void PrepareParameterSet(const LiveRun& run, FinishRecord& f) const;
  void PrepareMeasuredLimits(const LiveRun& run, FinishRecord& f);
  api::Status WriteFinish(const LiveRun& run, FinishRecord& f, bool with_results);
  api::Status ApproveRunSet(const LiveRun& run, std::int64_t set_id);
  void StoreFinish(const LiveRun& run, FinishRecord& f);
  void PublishFinish(LiveRun& run, const FinishRecord& f);

  storage::Database& db_;
  SampleHub& hub_;
  LiveRuns& runs_;
  protocols::BenchOwner& owner_;
  Log log_;

  std::mutex queue_mu_;
  std::condition_variable queue_cv_;
  std::deque<std::function<void()>> queue_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace fesbench::server::services
