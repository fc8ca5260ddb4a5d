#pragma once

/// @file
/// JSON forms of the analysis services' requests and results (DESIGN.md
/// §8 `identifications`, `predictions`, `comparisons`). Parsing is strict:
/// unknown fields, wrong types, non-integral ids and out-of-range values
/// are kInvalidArgument with the field path ("breakpoints.active_angle[2]",
/// "pairs[1].trial_ids[0]"); the service's own validation then runs on the
/// parsed value. Every physical quantity names its unit in its key.
///
/// Identification request:
///   {"session_id": 3 | "trial_ids": [..], "method": "thesis" | "rapid",
///    "irc_method": "ramp_correlation", "passive_method": "simultaneous",
///    "contraction_order": 3, "pole_method": "peak", "models": ["full", ..],
///    "breakpoints": {"passive_angle": 11 | [deg..], "passive_velocity": ..,
///                    "active_angle": .., "active_velocity": ..},
///    "inertia_kgm2": 0.36, "torque_angle_parameter_set_id": 4}
/// Prediction request:
///   {"parameter_set_id": 1, "trial_id": 2} or
///   {"parameter_set_id": 1, "stimulus": {"generator": "prediction_step",
///    "params": {"threshold_ma": 20, ..}}, "mode": "free_swing" | "isometric",
///    "initial_angle_deg": 90, "initial_velocity_deg_s": 0, "duration_s": 5}
/// Comparison request:
///   {"pairs": [{"a_parameter_set_id": 1, "b_parameter_set_id": 2,
///               "trial_ids": [5, 6]}, ..],
///    "metric": "e_rms", "confidence": 0.95}

#include <nlohmann/json.hpp>

#include "api/status.h"
#include "server/services/comparison_service.h"
#include "server/services/identification_service.h"
#include "server/services/prediction_service.h"

namespace fesbench::server::services {

api::Result<IdentificationRequest> IdentificationRequestFromJson(const nlohmann::json& json);
nlohmann::json IdentificationRequestToJson(const IdentificationRequest& request);
/// {"subject_id", "leg_id", "parameter_sets": [{"id", "version", "model"}],
///  "trial_ids", "report": {"fit_rms", "values", "warnings"}, "audit_id"}.
nlohmann::json IdentificationResultToJson(const IdentificationResult& result);

api::Result<PredictionRequest> PredictionRequestFromJson(const nlohmann::json& json);
nlohmann::json PredictionRequestToJson(const PredictionRequest& request);
/// {"channel", "unit", "samples", "e_rms", "e_abs", "max_abs",
///  "normalised_rms" (null if undefined), "normalised_samples_used", "e_ave"}.
nlohmann::json PredictionErrorsToJson(const PredictionErrors& errors);
/// {"prediction_id" (null until stored), "evaluation_id", "parameter_set_id",
///  "trial_id", "mode", "model", "initial_angle_deg", "initial_velocity_deg_s",
///  "sample_rate_hz", "columns": {"t_s", "stim_ma", "angle_deg",
///  "velocity_deg_s", "torque_nm", "activation"} (when include_columns),
///  "errors" (null without a trial)}.
nlohmann::json PredictionResultToJson(const PredictionResult& result, bool include_columns = true);

api::Result<ComparisonRequest> ComparisonRequestFromJson(const nlohmann::json& json);
/// {"metric", "unit", "pairs": [{"a_parameter_set_id", "b_parameter_set_id",
///  "subject_id", "leg_id", "a_error", "b_error", "trials": [{"trial_id",
///  "a_error", "b_error"}]}], "t_test": {"mean_difference", "sd_difference",
///  "n", "t", "df", "p_value", "confidence", "t_critical", "significant"}}.
nlohmann::json ComparisonResultToJson(const ComparisonResult& result);

}  // namespace fesbench::server::services

#include "server/services/job_pool.h"

namespace fesbench::server::services {

/// Queues service.Fit(actor, request) on `pool` as an "identification" job
/// whose result is IdentificationResultToJson; the job id, or the pool's
/// kUnavailable. `service` must outlive the job.
api::Result<std::int64_t> SubmitIdentification(JobPool& pool, IdentificationService& service,
                                               const Actor& actor, IdentificationRequest request);
/// The same for service.Predict ("prediction" job, PredictionResultToJson).
api::Result<std::int64_t> SubmitPrediction(JobPool& pool, PredictionService& service,
                                           const Actor& actor, PredictionRequest request);
/// The same for service.Compare ("comparison" job, ComparisonResultToJson).
api::Result<std::int64_t> SubmitComparison(JobPool& pool, const ComparisonService& service,
                                           const Actor& actor, ComparisonRequest request);

}  // namespace fesbench::server::services
