#pragma once

/// @file
/// The jobs of the analysis services as they travel (docs/API.md, "Jobs"):
/// their states, the error object every failure carries (HTTP error bodies
/// and failed jobs alike), and what a client reads of GET /jobs/{id}.

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>

#include "api/status.h"

namespace fesbench::api {

/// queued → running → done | failed.
enum class JobState { kQueued, kRunning, kDone, kFailed };

/// "queued", "running", "done", "failed".
std::string_view JobStateName(JobState state);
/// The state of a name; nullopt for any other.
std::optional<JobState> ParseJobState(std::string_view name);

/// {"code": "invalid_argument", "message", "field" (only when the error
/// names one)}: the error object of every error response and failed job.
nlohmann::json ErrorToJson(const Status& status);
/// The Status of an error object; an unknown or missing code reads as
/// kInternal, so a client never mistakes a failure for success.
Status ErrorFromJson(const nlohmann::json& error);

/// What a client needs of a job record: {"id", "kind", "state", "result"
/// (done), "error" (failed), …} (the server's record has more: who
/// submitted it and when).
struct JobReport {
  std::int64_t id = 0;
  std::string kind;
  JobState state = JobState::kQueued;
  nlohmann::json result;  ///< done: the job's value; otherwise null.
  Status error;           ///< failed: why; otherwise OK.
};

/// kInvalidArgument naming the field when the record lacks an id or a
/// known state.
Result<JobReport> JobReportFromJson(const nlohmann::json& job);

}  // namespace fesbench::api
