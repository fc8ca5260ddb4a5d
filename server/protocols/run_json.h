#pragma once

/// @file
/// JSON of what a run reports (DESIGN.md §8 runs/{id}, runs/{id}/stream):
/// the run summary, progress, live sample batches and safety events. Keys
/// carry units. Trials themselves go out as api::TrialToJson.

#include <nlohmann/json.hpp>

#include "server/protocols/runner.h"

namespace fesbench::server::protocols {

/// "stim_clamped", "setpoint_clamped", "estop", "estop_cleared", "watchdog".
std::string_view SafetyEventKindName(SafetyEvent::Kind kind);

/// {"kind", "t_s", "requested", "applied", "detail"} (NaN numbers as null).
nlohmann::json SafetyEventToJson(const SafetyEvent& event);

/// {"fraction", "eta_s", "bench_elapsed_s", "bench_total_s", "step", "phase"}.
nlohmann::json ProgressToJson(const Progress& progress);

/// {"trial", "trial_name", "t_s": [..], "stim_ma": [..], "angle_deg": [..],
///  "torque_nm": [..], "accel_m_s2": [..]}.
nlohmann::json SampleBatchToJson(const SampleBatch& batch);

/// {"state", "reason", "protocol", "protocol_version", "parameters": {..},
///  "trials": [{"name", "samples", "sample_rate_hz", "duration_s",
///  "complete", "offsets_nm"}], "values": {..}, "tolerance": {..} (if any),
///  "parameter_set": {..} (if any, api::ParameterSetToJson),
///  "safety_events": [..], "bench_duration_s", "wall_duration_s"}.
nlohmann::json RunResultToJson(const RunResult& result);

}  // namespace fesbench::server::protocols
