#include "server/services/analysis_json.h"

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "api/json_fields.h"

namespace fesbench::server::services {
namespace {

using nlohmann::json;

json ReportToJson(const model::IdentifyReport& r) {
  return {{"fit_rms", r.fit_rms}, {"values", r.values}, {"warnings", r.warnings}};
}

}  // namespace

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

json IdentificationResultToJson(const IdentificationResult& r) {
  json sets = json::array();
  for (const StoredFit& s : r.stored) {
    sets.push_back({{"id", s.parameter_set_id}, {"version", s.version}, {"model", s.model}});
  }
  return {{"subject_id", r.subject_id},       {"leg_id", r.leg_id},
          {"parameter_sets", sets},           {"trial_ids", r.trial_ids},
          {"report", ReportToJson(r.report)}, {"audit_id", r.audit_id}};
}

json PredictionErrorsToJson(const PredictionErrors& e) {
  return {{"channel", e.channel},
          {"unit", e.unit},
          {"samples", e.samples},
          {"e_rms", e.e_rms},
          {"e_abs", e.e_abs},
          {"max_abs", e.max_abs},
          {"normalised_rms", api::OrNull(e.normalised_rms)},
          {"normalised_samples_used", e.normalised_samples_used},
          {"e_ave", api::OrNull(e.e_ave)}};
}

json PredictionResultToJson(const PredictionResult& r, bool include_columns) {
  json j = {{"prediction_id", r.prediction_id > 0 ? json(r.prediction_id) : json(nullptr)},
            {"evaluation_id", api::OrNull(r.evaluation_id)},
            {"parameter_set_id", r.parameter_set_id},
            {"trial_id", api::OrNull(r.trial_id)},
            {"mode", PredictionModeName(r.mode)},
            {"model", r.model},
            {"initial_angle_deg", r.initial_angle_deg},
            {"initial_velocity_deg_s", r.initial_velocity_deg_s},
            {"samples", r.predicted.size()},
            {"errors", r.errors ? PredictionErrorsToJson(*r.errors) : json(nullptr)},
            {"fitted_scale", api::OrNull(r.fitted_scale)},
            {"share_outside_identified_ranges", api::OrNull(r.share_outside_identified_ranges)},
            {"released_at_s", api::OrNull(r.released_at_s)},
            {"strength_at_start", api::OrNull(r.strength_at_start)}};
  j["joint_limits"] = r.joint_limits ? json{{"min_angle_deg", r.joint_limits->min_angle_deg},
                                            {"max_angle_deg", r.joint_limits->max_angle_deg}}
                                     : json(nullptr);
  if (r.predicted.size() >= 2) {
    j["sample_rate_hz"] = 1.0 / (r.predicted.t_s[1] - r.predicted.t_s[0]);
  }
  if (include_columns) {
    j["columns"] = {{"t_s", r.predicted.t_s},
                    {"stim_ma", r.predicted.stim_ma},
                    {"angle_deg", r.predicted.angle_deg},
                    {"velocity_deg_s", r.predicted.velocity_deg_s},
                    {"torque_nm", r.predicted.torque_nm},
                    {"activation", r.predicted.activation}};
  }
  return j;
}

json ComparisonResultToJson(const ComparisonResult& r) {
  json pairs = json::array();
  for (const PairComparison& p : r.pairs) {
    json trials = json::array();
    for (const TrialComparison& t : p.trials) {
      trials.push_back({{"trial_id", t.trial_id}, {"a_error", t.a_error}, {"b_error", t.b_error}});
    }
    pairs.push_back({{"a_parameter_set_id", p.pair.a_parameter_set_id},
                     {"b_parameter_set_id", p.pair.b_parameter_set_id},
                     {"subject_id", p.subject_id},
                     {"leg_id", p.leg_id},
                     {"a_error", p.a_error},
                     {"b_error", p.b_error},
                     {"trials", trials}});
  }
  json test = nullptr;
  if (r.test) {
    const model::PairedTTestResult& t = *r.test;
    test = {{"mean_difference", t.mean_difference},
            {"sd_difference", t.sd_difference},
            {"n", t.n},
            {"t", t.t},
            {"df", t.df},
            {"p_value", t.p_value},
            {"confidence", t.confidence},
            {"t_critical", t.t_critical},
            {"significant", t.significant}};
  }
  return {{"metric", r.metric},
          {"unit", r.unit},
          {"pairs", pairs},
          {"t_test", test},
          {"t_test_note", r.test_note.empty() ? json(nullptr) : json(r.test_note)}};
}

json ModelCheckToJson(const ModelCheck& c) {
  json trials = json::array();
  for (const ModelCheckTrial& t : c.trials) {
    trials.push_back({{"trial_id", t.trial_id},
                      {"trial_name", t.trial_name},
                      {"session_id", t.session_id},
                      {"prediction_id", api::OrNull(t.prediction_id)},
                      {"quantity", t.quantity},
                      {"unit", t.unit},
                      {"e_rms", api::OrNull(t.e_rms)},
                      {"measured_range", api::OrNull(t.measured_range)},
                      {"share_outside_identified_ranges", api::OrNull(t.share_outside)},
                      {"verdict", ModelVerdictName(t.verdict)},
                      {"explanation", t.explanation}});
  }
  const ModelCheckThresholds& th = c.thresholds;
  return {{"parameter_set_id", c.parameter_set_id},
          {"verdict", ModelVerdictName(c.verdict)},
          {"summary", c.summary},
          {"thresholds",
           {{"angle_good_deg", th.angle_good_deg},
            {"angle_care_deg", th.angle_care_deg},
            {"torque_good_share", th.torque_good_share},
            {"torque_care_share", th.torque_care_share},
            {"outside_care_share", th.outside_care_share}}},
          {"trials", std::move(trials)},
          {"warnings", c.warnings},
          {"technical_warnings", c.technical_warnings}};
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
