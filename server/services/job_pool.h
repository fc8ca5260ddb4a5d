#pragma once

/// @file
/// A bounded pool of worker threads for long computations (identification,
/// prediction, comparison), separate from the bench's control thread so a
/// fit never delays a control tick (docs/ARCHITECTURE.md, "Inside the server"). A job is a
/// function returning JSON or a Status; its record (state, times, result or
/// error) stays queryable after it finishes, for the most recent
/// `history` jobs whose results together stay within `history_bytes`
/// (a prediction's result holds its columns: a few hundred KiB each, so a
/// count alone would let the pool hold hundreds of MiB over a long soak).
///
/// Thread-safe. Submit never blocks: a full queue is kUnavailable ("job queue
/// full"), which a client retries later.

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "api/job.h"
#include "api/status.h"
#include "server/services/actor.h"
#include "api/time_utc.h"

namespace fesbench::server::services {

struct JobPoolConfig {
  int workers = 2;                  ///< worker threads, 1–64.
  std::size_t queue_capacity = 64;  ///< queued (not yet running) jobs, ≥ 1.
  std::size_t history = 1000;       ///< finished records kept (oldest dropped), ≥ 1.
  /// Memory the kept results may take together (ApproximateJsonBytes); the
  /// oldest finished records are dropped beyond it, except the newest one.
  std::size_t history_bytes = 32u << 20;
  /// Clock of the submitted/started/finished stamps; outlives the pool.
  api::Clock* clock = api::Clock::Real();
};

/// queued → running → done | failed (api/job.h). Jobs still queued at
/// shutdown end failed with kUnavailable ("cancelled: job pool shutting down").
using JobState = api::JobState;
using api::JobStateName;

/// What a job computes: a JSON result, or the Status saying why not. An
/// exception escaping it is caught and recorded as kInternal.
using JobFunction = std::function<api::Result<nlohmann::json>()>;

/// The record of one job.
struct JobRecord {
  std::int64_t id = 0;  ///< 1, 2, … per pool.
  std::string kind;     ///< e.g. "identification".
  Actor actor;          ///< who submitted it.
  JobState state = JobState::kQueued;
  api::UtcTime submitted_at;
  std::optional<api::UtcTime> started_at;
  std::optional<api::UtcTime> finished_at;
  nlohmann::json result;         ///< done: the function's value; otherwise null.
  std::size_t result_bytes = 0;  ///< ApproximateJsonBytes(result) once done.
  api::Status error;             ///< failed: why; otherwise OK.
};

/// JSON of a record: {"id", "kind", "state", "submitted_by": {"user_id",
/// "user_name", "role"}, "submitted_at_utc", "started_at_utc",
/// "finished_at_utc" (null until set), "result" (done) or "error"
/// (failed, api::ErrorToJson)}.
nlohmann::json JobToJson(const JobRecord& job);

/// The heap a JSON value takes, approximately: one nlohmann::json node per
/// value (16 bytes), strings' characters, arrays' and objects' containers.
std::size_t ApproximateJsonBytes(const nlohmann::json& value);

class JobPool {
 public:
  /// Starts the workers. Invalid config values are clamped into their ranges.
  explicit JobPool(JobPoolConfig config = {});
  /// Shutdown(): queued jobs are cancelled, running ones finish, then join.
  ~JobPool();
  JobPool(const JobPool&) = delete;
  JobPool& operator=(const JobPool&) = delete;

  /// Queues fn. kInvalidArgument (field "kind") for an empty kind or an empty
  /// function; kUnavailable "job queue full" when queue_capacity jobs are
  /// waiting; kUnavailable after Shutdown.
  api::Result<std::int64_t> Submit(std::string kind, const Actor& actor, JobFunction fn);
  /// The record of job `id` (a copy); kNotFound for an unknown or forgotten id.
  api::Result<JobRecord> Get(std::int64_t id) const;
  /// The `limit` most recent jobs (queued, running and finished), newest first.
  std::vector<JobRecord> List(std::size_t limit = 50) const;
  /// Jobs waiting (not yet running).
  std::size_t queued() const;

  /// Stops accepting jobs. drain = true runs the queued jobs first; false
  /// marks them failed (cancelled). Running jobs always finish. Joins the
  /// workers; idempotent.
  void Shutdown(bool drain = false);

 private:
  void WorkerLoop();
  api::UtcTime Now() const;
  // Drops the oldest finished records beyond history or history_bytes (mu_ held).
  void Forget();

  JobPoolConfig config_;
  mutable std::mutex mu_;
  std::condition_variable wake_;
  std::deque<std::int64_t> queue_;
  std::map<std::int64_t, JobRecord> records_;
  std::map<std::int64_t, JobFunction> functions_;  // of queued jobs
  std::deque<std::int64_t> finished_order_;
  std::size_t finished_bytes_ = 0;  // ApproximateJsonBytes of the kept results
  std::int64_t next_id_ = 1;
  bool stopping_ = false;
  bool drain_ = false;
  std::vector<std::thread> workers_;
  std::mutex join_mu_;
};

}  // namespace fesbench::server::services
