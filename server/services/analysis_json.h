#pragma once

/// @file
/// Glue between the analysis services and their jobs (docs/API.md, "Jobs":
/// `identifications`, `predictions`, `comparisons`, model checks): the
/// requests read as the services take them (the wire form of
/// api/analysis_requests.h followed by the service's own validation, both
/// kInvalidArgument naming the field), a prediction's wire form, and the
/// submission of each job. The results' JSON is api/analysis_results.h.

#include <nlohmann/json.hpp>

#include "api/analysis_results.h"
#include "api/status.h"
#include "server/services/comparison_service.h"
#include "server/services/identification_service.h"
#include "server/services/model_check.h"
#include "server/services/prediction_service.h"

namespace fesbench::server::services {

/// api::IdentificationRequestFromJson, then ValidateIdentificationRequest.
api::Result<IdentificationRequest> ReadIdentificationRequest(const nlohmann::json& json);

/// api::PredictionRequestFromJson, then ValidatePredictionRequest.
api::Result<PredictionRequest> ReadPredictionRequest(const nlohmann::json& json);
/// What is sent of a prediction (api::PredictionView): the simulation's
/// sample count and rate, and its columns when `include_columns`.
api::PredictionView PredictionViewOf(const PredictionResult& result, bool include_columns = true);
/// api::PredictionViewToJson(PredictionViewOf(result, include_columns)).
nlohmann::json PredictionResultToJson(const PredictionResult& result, bool include_columns = true);

/// api::ComparisonRequestFromJson, then ValidateComparisonRequest.
api::Result<ComparisonRequest> ReadComparisonRequest(const nlohmann::json& json);

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
