#include "api/analysis_results.h"

#include <limits>
#include <map>
#include <utility>

#include "api/json_fields.h"
#include "api/json_read.h"
#include "api/name_table.h"

namespace fesbench::api {

namespace {

using nlohmann::json;

constexpr NameTable<ModelVerdict, 4> kModelVerdicts(
    {{{ModelVerdict::kGoodForControl, "good_for_control"},
      {ModelVerdict::kUseWithCare, "use_with_care"},
      {ModelVerdict::kDoNotUse, "do_not_use"},
      {ModelVerdict::kNoFreshTrials, "no_fresh_trials"}}},
    "do_not_use");

// The objects of the array `key`, each read by `read` with its own fields
// (path "key[i]"); a value that is not an array is the reader's failure.
template <typename T, typename Read>
void ReadFieldsList(JsonFields& in, std::string_view key, bool required, std::vector<T>& out, Read read) {
  const json* items = in.Any(key, required);
  if (items == nullptr) return;
  if (!items->is_array()) {
    in.Fail(key, "must be an array");
    return;
  }
  for (std::size_t i = 0; i < items->size(); ++i) {
    JsonFields item((*items)[i]);
    T value;
    read(item, value);
    if (!item.ok()) {
      in.Fail(std::string(key) + "[" + std::to_string(i) + "]." + item.status().field(),
              item.status().message());
      return;
    }
    out.push_back(std::move(value));
  }
}

// A nested object read by `read` with its own fields (path "key").
template <typename T, typename Read>
void ReadFieldsObject(JsonFields& in, std::string_view key, std::optional<T>& out, Read read) {
  const json* object = in.Object(key, false);
  if (object == nullptr) return;
  JsonFields fields(*object);
  T value;
  read(fields, value);
  if (!fields.ok()) {
    in.Fail(std::string(key) + "." + fields.status().field(), fields.status().message());
    return;
  }
  out = std::move(value);
}

// {name: number}; a value that is not a number (a NaN sent as null) reads as NaN.
void ReadNumberMap(JsonFields& in, std::string_view key, std::map<std::string, double>& out) {
  const json* object = in.Object(key, false);
  if (object == nullptr) return;
  for (const auto& [name, value] : object->items()) {
    out[name] = value.is_number() ? value.get<double>() : std::numeric_limits<double>::quiet_NaN();
  }
}

// A figure that may be undefined: JSON null (how a NaN travels) reads as NaN.
void ReadFigure(JsonFields& in, std::string_view key, double& out) {
  out = std::numeric_limits<double>::quiet_NaN();
  ReadInto(in, key, out);
}

void ReadReport(JsonFields& in, model::IdentifyReport& r) {
  ReadNumberMap(in, "fit_rms", r.fit_rms);
  ReadNumberMap(in, "values", r.values);
  ReadInto(in, "warnings", r.warnings);
}

void ReadStoredFit(JsonFields& in, StoredFit& s) {
  s.parameter_set_id = in.Integer("id", true).value_or(0);
  ReadInto(in, "version", s.version);
  ReadInto(in, "model", s.model);
}

void ReadErrors(JsonFields& in, PredictionErrors& e) {
  ReadInto(in, "channel", e.channel);
  ReadInto(in, "unit", e.unit);
  ReadInto(in, "samples", e.samples);
  ReadFigure(in, "e_rms", e.e_rms);
  ReadFigure(in, "e_abs", e.e_abs);
  ReadFigure(in, "max_abs", e.max_abs);
  ReadInto(in, "normalised_rms", e.normalised_rms);
  ReadInto(in, "normalised_samples_used", e.normalised_samples_used);
  ReadInto(in, "e_ave", e.e_ave);
}

json ColumnsToJson(const PredictionColumns& c) {
  return {{"t_s", c.t_s},
          {"stim_ma", c.stim_ma},
          {"angle_deg", c.angle_deg},
          {"velocity_deg_s", c.velocity_deg_s},
          {"torque_nm", c.torque_nm},
          {"activation", c.activation}};
}

void ReadColumns(JsonFields& in, PredictionColumns& c) {
  ReadInto(in, "t_s", c.t_s);
  ReadInto(in, "stim_ma", c.stim_ma);
  ReadInto(in, "angle_deg", c.angle_deg);
  ReadInto(in, "velocity_deg_s", c.velocity_deg_s);
  ReadInto(in, "torque_nm", c.torque_nm);
  ReadInto(in, "activation", c.activation);
}

void ReadJointLimits(JsonFields& in, model::JointLimits& limits) {
  ReadInto(in, "min_angle_deg", limits.min_angle_deg);
  ReadInto(in, "max_angle_deg", limits.max_angle_deg);
}

json TTestToJson(const model::PairedTTestResult& t) {
  return {{"mean_difference", t.mean_difference},
          {"sd_difference", t.sd_difference},
          {"n", t.n},
          {"t", t.t},
          {"df", t.df},
          {"p_value", t.p_value},
          {"confidence", t.confidence},
          {"t_critical", t.t_critical},
          {"significant", t.significant}};
}

void ReadTTest(JsonFields& in, model::PairedTTestResult& t) {
  ReadFigure(in, "mean_difference", t.mean_difference);
  ReadFigure(in, "sd_difference", t.sd_difference);
  ReadInto(in, "n", t.n);
  ReadFigure(in, "t", t.t);
  ReadFigure(in, "df", t.df);
  ReadFigure(in, "p_value", t.p_value);
  ReadInto(in, "confidence", t.confidence);
  ReadFigure(in, "t_critical", t.t_critical);
  ReadInto(in, "significant", t.significant);
}

void ReadTrialComparison(JsonFields& in, TrialComparison& t) {
  t.trial_id = in.Integer("trial_id", true).value_or(0);
  ReadFigure(in, "a_error", t.a_error);
  ReadFigure(in, "b_error", t.b_error);
}

void ReadPair(JsonFields& in, PairComparison& p) {
  ReadInto(in, "a_parameter_set_id", p.a_parameter_set_id);
  ReadInto(in, "b_parameter_set_id", p.b_parameter_set_id);
  ReadInto(in, "subject_id", p.subject_id);
  ReadInto(in, "leg_id", p.leg_id);
  ReadFigure(in, "a_error", p.a_error);
  ReadFigure(in, "b_error", p.b_error);
  ReadFieldsList(in, "trials", false, p.trials, &ReadTrialComparison);
}

json ThresholdsToJson(const ModelCheckThresholds& th) {
  return {{"angle_good_deg", th.angle_good_deg},
          {"angle_care_deg", th.angle_care_deg},
          {"torque_good_share", th.torque_good_share},
          {"torque_care_share", th.torque_care_share},
          {"outside_care_share", th.outside_care_share}};
}

void ReadThresholds(JsonFields& in, ModelCheckThresholds& th) {
  ReadInto(in, "angle_good_deg", th.angle_good_deg);
  ReadInto(in, "angle_care_deg", th.angle_care_deg);
  ReadInto(in, "torque_good_share", th.torque_good_share);
  ReadInto(in, "torque_care_share", th.torque_care_share);
  ReadInto(in, "outside_care_share", th.outside_care_share);
}

json CheckTrialToJson(const ModelCheckTrial& t) {
  return {{"trial_id", t.trial_id},
          {"trial_name", t.trial_name},
          {"session_id", t.session_id},
          {"prediction_id", OrNull(t.prediction_id)},
          {"quantity", t.quantity},
          {"unit", t.unit},
          {"e_rms", OrNull(t.e_rms)},
          {"measured_range", OrNull(t.measured_range)},
          {"share_outside_identified_ranges", OrNull(t.share_outside)},
          {"verdict", ModelVerdictName(t.verdict)},
          {"explanation", t.explanation}};
}

void ReadCheckTrial(JsonFields& in, ModelCheckTrial& t) {
  t.trial_id = in.Integer("trial_id", true).value_or(0);
  ReadInto(in, "trial_name", t.trial_name);
  ReadInto(in, "session_id", t.session_id);
  ReadInto(in, "prediction_id", t.prediction_id);
  ReadInto(in, "quantity", t.quantity);
  ReadInto(in, "unit", t.unit);
  ReadInto(in, "e_rms", t.e_rms);
  ReadInto(in, "measured_range", t.measured_range);
  ReadInto(in, "share_outside_identified_ranges", t.share_outside);
  ReadNamed(in, "verdict", true, t.verdict, &ParseModelVerdict);
  ReadInto(in, "explanation", t.explanation);
}

bool SameReport(const model::IdentifyReport& a, const model::IdentifyReport& b) {
  return a.fit_rms == b.fit_rms && a.values == b.values && a.warnings == b.warnings;
}

bool SameTTest(const model::PairedTTestResult& a, const model::PairedTTestResult& b) {
  return a.mean_difference == b.mean_difference && a.sd_difference == b.sd_difference &&
         a.n == b.n && a.t == b.t && a.df == b.df && a.p_value == b.p_value &&
         a.confidence == b.confidence && a.t_critical == b.t_critical &&
         a.significant == b.significant;
}

}  // namespace

bool operator==(const IdentificationResult& a, const IdentificationResult& b) {
  return a.subject_id == b.subject_id && a.leg_id == b.leg_id && a.stored == b.stored &&
         a.trial_ids == b.trial_ids && SameReport(a.report, b.report) && a.audit_id == b.audit_id;
}

bool operator==(const ComparisonResult& a, const ComparisonResult& b) {
  const bool same_test = a.test.has_value() == b.test.has_value() &&
                         (!a.test.has_value() || SameTTest(*a.test, *b.test));
  return a.metric == b.metric && a.unit == b.unit && a.pairs == b.pairs && same_test &&
         a.test_note == b.test_note;
}

json IdentifyReportToJson(const model::IdentifyReport& r) {
  return {{"fit_rms", r.fit_rms}, {"values", r.values}, {"warnings", r.warnings}};
}

json IdentificationResultToJson(const IdentificationResult& r) {
  json sets = json::array();
  for (const StoredFit& s : r.stored) {
    sets.push_back({{"id", s.parameter_set_id}, {"version", s.version}, {"model", s.model}});
  }
  return {{"subject_id", r.subject_id},
          {"leg_id", r.leg_id},
          {"parameter_sets", sets},
          {"trial_ids", r.trial_ids},
          {"report", IdentifyReportToJson(r.report)},
          {"audit_id", r.audit_id}};
}

Result<IdentificationResult> IdentificationResultFromJson(const json& j) {
  JsonFields in(j);
  IdentificationResult r;
  ReadInto(in, "subject_id", r.subject_id);
  ReadInto(in, "leg_id", r.leg_id);
  ReadFieldsList(in, "parameter_sets", true, r.stored, &ReadStoredFit);
  ReadInto(in, "trial_ids", r.trial_ids);
  std::optional<model::IdentifyReport> report;
  ReadFieldsObject(in, "report", report, &ReadReport);
  if (report) r.report = *std::move(report);
  ReadInto(in, "audit_id", r.audit_id);
  return ReadResult(in, std::move(r));
}

json PredictionErrorsToJson(const PredictionErrors& e) {
  return {{"channel", e.channel},
          {"unit", e.unit},
          {"samples", e.samples},
          {"e_rms", e.e_rms},
          {"e_abs", e.e_abs},
          {"max_abs", e.max_abs},
          {"normalised_rms", OrNull(e.normalised_rms)},
          {"normalised_samples_used", e.normalised_samples_used},
          {"e_ave", OrNull(e.e_ave)}};
}

Result<PredictionErrors> PredictionErrorsFromJson(const json& j) {
  JsonFields in(j);
  PredictionErrors e;
  ReadErrors(in, e);
  return ReadResult(in, std::move(e));
}

json PredictionViewToJson(const PredictionView& v) {
  json j = {{"prediction_id", OrNull(v.prediction_id)},
            {"evaluation_id", OrNull(v.evaluation_id)},
            {"parameter_set_id", v.parameter_set_id},
            {"trial_id", OrNull(v.trial_id)},
            {"mode", PredictionModeName(v.mode)},
            {"model", v.model},
            {"initial_angle_deg", v.initial_angle_deg},
            {"initial_velocity_deg_s", v.initial_velocity_deg_s},
            {"samples", v.samples},
            {"errors", v.errors ? PredictionErrorsToJson(*v.errors) : json(nullptr)},
            {"fitted_scale", OrNull(v.fitted_scale)},
            {"share_outside_identified_ranges", OrNull(v.share_outside_identified_ranges)},
            {"released_at_s", OrNull(v.released_at_s)},
            {"strength_at_start", OrNull(v.strength_at_start)}};
  j["joint_limits"] = v.joint_limits ? json{{"min_angle_deg", v.joint_limits->min_angle_deg},
                                            {"max_angle_deg", v.joint_limits->max_angle_deg}}
                                     : json(nullptr);
  if (v.sample_rate_hz) j["sample_rate_hz"] = *v.sample_rate_hz;
  if (v.columns) j["columns"] = ColumnsToJson(*v.columns);
  return j;
}

Result<PredictionView> PredictionViewFromJson(const json& j) {
  JsonFields in(j);
  PredictionView v;
  ReadInto(in, "prediction_id", v.prediction_id);
  ReadInto(in, "evaluation_id", v.evaluation_id);
  v.parameter_set_id = in.Integer("parameter_set_id", true).value_or(0);
  ReadInto(in, "trial_id", v.trial_id);
  ReadNamed(in, "mode", true, v.mode, &ParsePredictionMode);
  ReadInto(in, "model", v.model);
  ReadInto(in, "initial_angle_deg", v.initial_angle_deg);
  ReadInto(in, "initial_velocity_deg_s", v.initial_velocity_deg_s);
  ReadInto(in, "samples", v.samples);
  ReadInto(in, "sample_rate_hz", v.sample_rate_hz);
  ReadFieldsObject(in, "columns", v.columns, &ReadColumns);
  ReadFieldsObject(in, "errors", v.errors, &ReadErrors);
  ReadInto(in, "fitted_scale", v.fitted_scale);
  ReadInto(in, "share_outside_identified_ranges", v.share_outside_identified_ranges);
  ReadInto(in, "released_at_s", v.released_at_s);
  ReadInto(in, "strength_at_start", v.strength_at_start);
  ReadFieldsObject(in, "joint_limits", v.joint_limits, &ReadJointLimits);
  return ReadResult(in, std::move(v));
}

json ComparisonResultToJson(const ComparisonResult& r) {
  json pairs = json::array();
  for (const PairComparison& p : r.pairs) {
    json trials = json::array();
    for (const TrialComparison& t : p.trials) {
      trials.push_back({{"trial_id", t.trial_id}, {"a_error", t.a_error}, {"b_error", t.b_error}});
    }
    pairs.push_back({{"a_parameter_set_id", p.a_parameter_set_id},
                     {"b_parameter_set_id", p.b_parameter_set_id},
                     {"subject_id", p.subject_id},
                     {"leg_id", p.leg_id},
                     {"a_error", p.a_error},
                     {"b_error", p.b_error},
                     {"trials", std::move(trials)}});
  }
  return {{"metric", r.metric},
          {"unit", r.unit},
          {"pairs", std::move(pairs)},
          {"t_test", r.test ? TTestToJson(*r.test) : json(nullptr)},
          {"t_test_note", r.test_note.empty() ? json(nullptr) : json(r.test_note)}};
}

Result<ComparisonResult> ComparisonResultFromJson(const json& j) {
  JsonFields in(j);
  ComparisonResult r;
  r.metric = in.String("metric", true).value_or("");
  ReadInto(in, "unit", r.unit);
  ReadFieldsList(in, "pairs", true, r.pairs, &ReadPair);
  ReadFieldsObject(in, "t_test", r.test, &ReadTTest);
  ReadInto(in, "t_test_note", r.test_note);
  return ReadResult(in, std::move(r));
}

std::string_view ModelVerdictName(ModelVerdict verdict) { return kModelVerdicts.Name(verdict); }

std::optional<ModelVerdict> ParseModelVerdict(std::string_view name) {
  return kModelVerdicts.Parse(name);
}

json ModelCheckToJson(const ModelCheck& c) {
  json trials = json::array();
  for (const ModelCheckTrial& t : c.trials) trials.push_back(CheckTrialToJson(t));
  return {{"parameter_set_id", c.parameter_set_id},
          {"verdict", ModelVerdictName(c.verdict)},
          {"summary", c.summary},
          {"thresholds", ThresholdsToJson(c.thresholds)},
          {"trials", std::move(trials)},
          {"warnings", c.warnings},
          {"technical_warnings", c.technical_warnings}};
}

Result<ModelCheck> ModelCheckFromJson(const json& j) {
  JsonFields in(j);
  ModelCheck c;
  c.parameter_set_id = in.Integer("parameter_set_id", true).value_or(0);
  ReadNamed(in, "verdict", true, c.verdict, &ParseModelVerdict);
  ReadInto(in, "summary", c.summary);
  std::optional<ModelCheckThresholds> thresholds;
  ReadFieldsObject(in, "thresholds", thresholds, &ReadThresholds);
  if (thresholds) c.thresholds = *thresholds;
  ReadFieldsList(in, "trials", false, c.trials, &ReadCheckTrial);
  ReadInto(in, "warnings", c.warnings);
  ReadInto(in, "technical_warnings", c.technical_warnings);
  return ReadResult(in, std::move(c));
}

}  // namespace fesbench::api
