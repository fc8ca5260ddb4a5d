#pragma once

/// @file
/// JSON of a runner's result (what a run produced, for tests and logs).
/// The run's wire forms (progress, safety events, sample batches, the run
/// resource) are in api/run.h; trials go out as api::TrialToJson.

#include <nlohmann/json.hpp>

#include "server/protocols/runner.h"

namespace fesbench::server::protocols {

/// {"state", "reason", "protocol", "protocol_version", "parameters": {..},
///  "trials": [{"name", "samples", "sample_rate_hz", "duration_s",
///  "complete", "offsets_nm"}], "values": {..}, "tolerance": {..} (if any),
///  "parameter_set": {..} (if any, api::ParameterSetToJson),
///  "safety_events": [..], "bench_duration_s", "wall_duration_s"}.
nlohmann::json RunResultToJson(const RunResult& result);

}  // namespace fesbench::server::protocols
