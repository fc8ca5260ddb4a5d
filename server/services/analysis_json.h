#pragma once

/// @file
/// JSON of the analysis services' results (docs/API.md, "Jobs": `identifications`,
/// `predictions`, `comparisons`), and the requests read as the services
/// take them: the wire form (api/analysis_requests.h) followed by the
/// service's own validation, both kInvalidArgument naming the field.

#include <nlohmann/json.hpp>

#include "api/status.h"
#include "server/services/comparison_service.h"
#include "server/services/identification_service.h"
#include "server/services/model_check.h"
#include "server/services/prediction_service.h"

namespace fesbench::server::services {

/// api::IdentificationRequestFromJson, then ValidateIdentificationRequest.
api::Result<IdentificationRequest> ReadIdentificationRequest(const nlohmann::json& json);
/// {"subject_id", "leg_id", "parameter_sets": [{"id", "version", "model"}],
///  "trial_ids", "report": {"fit_rms", "values", "warnings"}, "audit_id"}.
nlohmann::json IdentificationResultToJson(const IdentificationResult& result);

/// api::PredictionRequestFromJson, then ValidatePredictionRequest.
api::Result<PredictionRequest> ReadPredictionRequest(const nlohmann::json& json);
/// {"channel", "unit", "samples", "e_rms", "e_abs", "max_abs",
///  "normalised_rms" (null if undefined), "normalised_samples_used", "e_ave"}.
nlohmann::json PredictionErrorsToJson(const PredictionErrors& errors);
/// {"prediction_id" (null until stored), "evaluation_id", "parameter_set_id",
///  "trial_id", "mode", "model", "initial_angle_deg", "initial_velocity_deg_s",
///  "sample_rate_hz", "columns": {"t_s", "stim_ma", "angle_deg",
///  "velocity_deg_s", "torque_nm", "activation"} (when include_columns),
///  "errors" (null without a trial)}.
nlohmann::json PredictionResultToJson(const PredictionResult& result, bool include_columns = true);

/// api::ComparisonRequestFromJson, then ValidateComparisonRequest.
api::Result<ComparisonRequest> ReadComparisonRequest(const nlohmann::json& json);
/// {"metric", "unit", "pairs": [{"a_parameter_set_id", "b_parameter_set_id",
///  "subject_id", "leg_id", "a_error", "b_error", "trials": [{"trial_id",
///  "a_error", "b_error"}]}], "t_test": {"mean_difference", "sd_difference",
///  "n", "t", "df", "p_value", "confidence", "t_critical", "significant"}}.
nlohmann::json ComparisonResultToJson(const ComparisonResult& result);

/// {"parameter_set_id", "verdict", "summary", "thresholds": {...}, "trials":
///  [{"trial_id", "trial_name", "session_id", "prediction_id", "quantity",
///  "unit", "e_rms", "measured_range", "share_outside_identified_ranges",
///  "verdict", "explanation"}], "warnings", "technical_warnings"}.
nlohmann::json ModelCheckToJson(const ModelCheck& check);

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
/// CheckModel(db, service, actor, id) as a "model_check" job (ModelCheckToJson).
api::Result<std::int64_t> SubmitModelCheck(JobPool& pool, storage::Database& db,
                                           PredictionService& service, const Actor& actor,
                                           std::int64_t parameter_set_id);
/// The same for service.Compare ("comparison" job, ComparisonResultToJson).
api::Result<std::int64_t> SubmitComparison(JobPool& pool, const ComparisonService& service,
                                           const Actor& actor, ComparisonRequest request);

}  // namespace fesbench::server::services
