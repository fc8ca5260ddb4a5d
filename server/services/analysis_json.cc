#include "server/services/analysis_json.h"

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace fesbench::server::services {

using nlohmann::json;

api::Result<IdentificationRequest> ReadIdentificationRequest(const json& j) {
  api::Result<IdentificationRequest> request = api::IdentificationRequestFromJson(j);
  if (!request.ok()) return request;
  if (api::Status s = ValidateIdentificationRequest(*request); !s.ok()) return s;
  return request;
}

api::Result<PredictionRequest> ReadPredictionRequest(const json& j) {
  api::Result<PredictionRequest> request = api::PredictionRequestFromJson(j);
  if (!request.ok()) return request;
  if (api::Status s = ValidatePredictionRequest(*request); !s.ok()) return s;
  return request;
}

api::Result<ComparisonRequest> ReadComparisonRequest(const json& j) {
  api::Result<ComparisonRequest> request = api::ComparisonRequestFromJson(j);
  if (!request.ok()) return request;
  if (api::Status s = ValidateComparisonRequest(*request); !s.ok()) return s;
  return request;
}

api::PredictionView PredictionViewOf(const PredictionResult& r, bool include_columns) {
  api::PredictionView v;
  if (r.prediction_id > 0) v.prediction_id = r.prediction_id;
  v.evaluation_id = r.evaluation_id;
  v.parameter_set_id = r.parameter_set_id;
  v.trial_id = r.trial_id;
  v.mode = r.mode;
  v.model = r.model;
  v.initial_angle_deg = r.initial_angle_deg;
  v.initial_velocity_deg_s = r.initial_velocity_deg_s;
  v.samples = r.predicted.size();
  if (r.predicted.size() >= 2) v.sample_rate_hz = 1.0 / (r.predicted.t_s[1] - r.predicted.t_s[0]);
  if (include_columns) {
    v.columns = api::PredictionColumns{r.predicted.t_s,       r.predicted.stim_ma,
                                       r.predicted.angle_deg, r.predicted.velocity_deg_s,
                                       r.predicted.torque_nm, r.predicted.activation};
  }
  v.errors = r.errors;
  v.fitted_scale = r.fitted_scale;
  v.share_outside_identified_ranges = r.share_outside_identified_ranges;
  v.released_at_s = r.released_at_s;
  v.strength_at_start = r.strength_at_start;
  v.joint_limits = r.joint_limits;
  return v;
}

json PredictionResultToJson(const PredictionResult& r, bool include_columns) {
  return api::PredictionViewToJson(PredictionViewOf(r, include_columns));
}

}  // namespace fesbench::server::services

namespace fesbench::server::services {

api::Result<std::int64_t> SubmitIdentification(JobPool& pool, IdentificationService& service,
                                               const Actor& actor, IdentificationRequest request) {
  return pool.Submit(
      "identification", actor,
      [&service, actor, request = std::move(request)]() -> api::Result<nlohmann::json> {
        api::Result<IdentificationResult> r = service.Fit(actor, request);
        if (!r.ok()) return r.status();
        return IdentificationResultToJson(*r);
      });
}

api::Result<std::int64_t> SubmitPrediction(JobPool& pool, PredictionService& service,
                                           const Actor& actor, PredictionRequest request) {
  return pool.Submit(
      "prediction", actor,
      [&service, actor, request = std::move(request)]() -> api::Result<nlohmann::json> {
        api::Result<PredictionResult> r = service.Predict(actor, request);
        if (!r.ok()) return r.status();
        return PredictionResultToJson(*r);
      });
}

api::Result<std::int64_t> SubmitModelCheck(JobPool& pool, storage::Database& db,
                                           PredictionService& service, const Actor& actor,
                                           std::int64_t parameter_set_id) {
  return pool.Submit("model_check", actor,
                     [&db, &service, actor, parameter_set_id]() -> api::Result<nlohmann::json> {
                       api::Result<ModelCheck> r =
                           CheckModel(db, service, actor, parameter_set_id);
                       if (!r.ok()) return r.status();
                       return ModelCheckToJson(*r);
                     });
}

api::Result<std::int64_t> SubmitComparison(JobPool& pool, const ComparisonService& service,
                                           const Actor& actor, ComparisonRequest request) {
  return pool.Submit("comparison", actor,
                     [&service, request = std::move(request)]() -> api::Result<nlohmann::json> {
                       api::Result<ComparisonResult> r = service.Compare(request);
                       if (!r.ok()) return r.status();
                       return ComparisonResultToJson(*r);
                     });
}

}  // namespace fesbench::server::services
