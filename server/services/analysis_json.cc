#include "server/services/analysis_json.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace fesbench::server::services {
namespace {

using nlohmann::json;

// Thrown only inside this file and caught by each *FromJson.
struct ParseError {
  api::Status status;
};

[[noreturn]] void Fail(const std::string& field, const std::string& message) {
  throw ParseError{api::Status::InvalidArgument(message, field)};
}

std::string Join(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

// Reads the fields of one JSON object; Done() rejects the fields not read.
class Fields {
 public:
  Fields(const json& j, std::string path) : j_(j), path_(std::move(path)) {
    if (!j_.is_object()) Fail(path_.empty() ? "body" : path_, "must be a JSON object");
  }
  const json* Get(const std::string& key) {
    known_.insert(key);
    const auto it = j_.find(key);
    return (it == j_.end() || it->is_null()) ? nullptr : &*it;
  }
  std::string Path(const std::string& key) const { return Join(path_, key); }
  void Done() const {
    for (const auto& [k, v] : j_.items()) {
      if (!known_.count(k)) Fail(Join(path_, k), "unknown field");
    }
  }

 private:
  const json& j_;
  std::string path_;
  std::set<std::string> known_;
};

std::int64_t Id(const json& v, const std::string& field) {
  if (!v.is_number_integer() || v.get<std::int64_t>() <= 0) {
    Fail(field, "must be a positive integer id");
  }
  return v.get<std::int64_t>();
}

double Number(const json& v, const std::string& field) {
  if (!v.is_number()) Fail(field, "must be a number");
  const double d = v.get<double>();
  if (!std::isfinite(d)) Fail(field, "must be finite");
  return d;
}

int Integer(const json& v, const std::string& field, int lo, int hi) {
  if (!v.is_number_integer()) Fail(field, "must be an integer");
  const auto i = v.get<std::int64_t>();
  if (i < lo || i > hi) {
    Fail(field, "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  }
  return static_cast<int>(i);
}

std::string Text(const json& v, const std::string& field) {
  if (!v.is_string()) Fail(field, "must be a string");
  return v.get<std::string>();
}

std::vector<std::int64_t> Ids(const json& v, const std::string& field) {
  if (!v.is_array()) Fail(field, "must be an array of ids");
  std::vector<std::int64_t> out;
  for (std::size_t i = 0; i < v.size(); ++i) {
    out.push_back(Id(v[i], field + "[" + std::to_string(i) + "]"));
  }
  return out;
}

model::BreakpointSpec Breakpoints(const json& v, const std::string& field) {
  model::BreakpointSpec spec;
  if (v.is_number_integer()) {
    spec.count = Integer(v, field, 2, 101);
    return spec;
  }
  if (!v.is_array()) Fail(field, "must be a count (integer) or an array of breakpoints");
  for (std::size_t i = 0; i < v.size(); ++i) {
    spec.explicit_x.push_back(Number(v[i], field + "[" + std::to_string(i) + "]"));
  }
  return spec;
}

template <typename T, typename F>
api::Result<T> Parse(F&& f) {
  try {
    return f();
  } catch (const ParseError& e) {
    return e.status;
  } catch (const json::exception& e) {
    return api::Status::InvalidArgument(std::string("malformed JSON value: ") + e.what());
  }
}

json Nullable(const std::optional<double>& v) { return v ? json(*v) : json(nullptr); }
json Nullable(const std::optional<std::int64_t>& v) { return v ? json(*v) : json(nullptr); }

json SpecToJson(const model::BreakpointSpec& s) {
  return s.explicit_x.empty() ? json(s.count) : json(s.explicit_x);
}

json ReportToJson(const model::IdentifyReport& r) {
  return {{"fit_rms", r.fit_rms}, {"values", r.values}, {"warnings", r.warnings}};
}

}  // namespace

api::Result<IdentificationRequest> IdentificationRequestFromJson(const json& j) {
  return Parse<IdentificationRequest>([&] {
    IdentificationRequest r;
    Fields f(j, "");
    if (const json* v = f.Get("session_id")) r.session_id = Id(*v, "session_id");
    if (const json* v = f.Get("trial_ids")) r.trial_ids = Ids(*v, "trial_ids");
    if (const json* v = f.Get("method")) r.method = Text(*v, "method");
    if (const json* v = f.Get("irc_method")) r.irc_method = Text(*v, "irc_method");
    if (const json* v = f.Get("passive_method")) r.passive_method = Text(*v, "passive_method");
    if (const json* v = f.Get("contraction_order")) {
      r.contraction_order = Integer(*v, "contraction_order", 0, 3);
    }
    if (const json* v = f.Get("pole_method")) r.pole_method = Text(*v, "pole_method");
    if (const json* v = f.Get("models")) {
      if (!v->is_array()) Fail("models", "must be an array of model names");
      r.models.clear();
      for (std::size_t i = 0; i < v->size(); ++i) {
        r.models.push_back(Text((*v)[i], "models[" + std::to_string(i) + "]"));
      }
    }
    if (const json* v = f.Get("breakpoints")) {
      Fields b(*v, "breakpoints");
      const auto read = [&](const char* key, std::optional<model::BreakpointSpec>& dst) {
        if (const json* x = b.Get(key)) dst = Breakpoints(*x, b.Path(key));
      };
      read("passive_angle", r.breakpoints.passive_angle);
      read("passive_velocity", r.breakpoints.passive_velocity);
      read("active_angle", r.breakpoints.active_angle);
      read("active_velocity", r.breakpoints.active_velocity);
      b.Done();
    }
    if (const json* v = f.Get("inertia_kgm2")) r.inertia_kgm2 = Number(*v, "inertia_kgm2");
    if (const json* v = f.Get("torque_angle_parameter_set_id")) {
      r.torque_angle_parameter_set_id = Id(*v, "torque_angle_parameter_set_id");
    }
    f.Done();
    if (api::Status s = ValidateIdentificationRequest(r); !s.ok()) throw ParseError{s};
    return r;
  });
}

json IdentificationRequestToJson(const IdentificationRequest& r) {
  json j = {{"method", r.method},
            {"irc_method", r.irc_method},
            {"passive_method", r.passive_method},
            {"contraction_order", r.contraction_order},
            {"pole_method", r.pole_method},
            {"models", r.models}};
  if (r.session_id) j["session_id"] = *r.session_id;
  if (!r.trial_ids.empty()) j["trial_ids"] = r.trial_ids;
  json bp = json::object();
  if (r.breakpoints.passive_angle) bp["passive_angle"] = SpecToJson(*r.breakpoints.passive_angle);
  if (r.breakpoints.passive_velocity) {
    bp["passive_velocity"] = SpecToJson(*r.breakpoints.passive_velocity);
  }
  if (r.breakpoints.active_angle) bp["active_angle"] = SpecToJson(*r.breakpoints.active_angle);
  if (r.breakpoints.active_velocity) {
    bp["active_velocity"] = SpecToJson(*r.breakpoints.active_velocity);
  }
  j["breakpoints"] = bp;
  if (r.inertia_kgm2) j["inertia_kgm2"] = *r.inertia_kgm2;
  if (r.torque_angle_parameter_set_id) {
    j["torque_angle_parameter_set_id"] = *r.torque_angle_parameter_set_id;
  }
  return j;
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

api::Result<PredictionRequest> PredictionRequestFromJson(const json& j) {
  return Parse<PredictionRequest>([&] {
    PredictionRequest r;
    Fields f(j, "");
    const json* set = f.Get("parameter_set_id");
    if (set == nullptr) Fail("parameter_set_id", "required");
    r.parameter_set_id = Id(*set, "parameter_set_id");
    if (const json* v = f.Get("trial_id")) r.trial_id = Id(*v, "trial_id");
    if (const json* v = f.Get("stimulus")) {
      Fields s(*v, "stimulus");
      StimulusSpec spec;
      const json* g = s.Get("generator");
      if (g == nullptr) Fail("stimulus.generator", "required");
      spec.generator = Text(*g, "stimulus.generator");
      if (const json* p = s.Get("params")) {
        if (!p->is_object()) Fail("stimulus.params", "must be an object of numbers");
        for (const auto& [k, x] : p->items()) spec.params[k] = Number(x, "stimulus.params." + k);
      }
      s.Done();
      r.stimulus = std::move(spec);
    }
    if (const json* v = f.Get("mode")) {
      const std::string m = Text(*v, "mode");
      if (m == "free_swing") {
        r.mode = PredictionMode::kFreeSwing;
      } else if (m == "isometric") {
        r.mode = PredictionMode::kIsometric;
      } else {
        Fail("mode", "must be free_swing or isometric");
      }
    }
    if (const json* v = f.Get("initial_angle_deg")) {
      r.initial_angle_deg = Number(*v, "initial_angle_deg");
    }
    if (const json* v = f.Get("initial_velocity_deg_s")) {
      r.initial_velocity_deg_s = Number(*v, "initial_velocity_deg_s");
    }
    if (const json* v = f.Get("duration_s")) r.duration_s = Number(*v, "duration_s");
    if (const json* v = f.Get("fit_scale")) {
      if (!v->is_boolean()) Fail("fit_scale", "must be true or false");
      r.fit_scale = v->get<bool>();
    }
    f.Done();
    if (api::Status s = ValidatePredictionRequest(r); !s.ok()) throw ParseError{s};
    return r;
  });
}

json PredictionRequestToJson(const PredictionRequest& r) {
  json j = {{"parameter_set_id", r.parameter_set_id}};
  if (r.trial_id) j["trial_id"] = *r.trial_id;
  if (r.stimulus) {
    json params = json::object();
    for (const auto& [k, v] : r.stimulus->params) params[k] = v;
    j["stimulus"] = {{"generator", r.stimulus->generator}, {"params", params}};
  }
  if (r.mode) j["mode"] = PredictionModeName(*r.mode);
  if (r.initial_angle_deg) j["initial_angle_deg"] = *r.initial_angle_deg;
  if (r.stimulus) j["initial_velocity_deg_s"] = r.initial_velocity_deg_s;
  if (r.duration_s) j["duration_s"] = *r.duration_s;
  if (r.fit_scale) j["fit_scale"] = true;
  return j;
}

json PredictionErrorsToJson(const PredictionErrors& e) {
  return {{"channel", e.channel},
          {"unit", e.unit},
          {"samples", e.samples},
          {"e_rms", e.e_rms},
          {"e_abs", e.e_abs},
          {"max_abs", e.max_abs},
          {"normalised_rms", Nullable(e.normalised_rms)},
          {"normalised_samples_used", e.normalised_samples_used},
          {"e_ave", Nullable(e.e_ave)}};
}

json PredictionResultToJson(const PredictionResult& r, bool include_columns) {
  json j = {{"prediction_id", r.prediction_id > 0 ? json(r.prediction_id) : json(nullptr)},
            {"evaluation_id", Nullable(r.evaluation_id)},
            {"parameter_set_id", r.parameter_set_id},
            {"trial_id", Nullable(r.trial_id)},
            {"mode", PredictionModeName(r.mode)},
            {"model", r.model},
            {"initial_angle_deg", r.initial_angle_deg},
            {"initial_velocity_deg_s", r.initial_velocity_deg_s},
            {"samples", r.predicted.size()},
            {"errors", r.errors ? PredictionErrorsToJson(*r.errors) : json(nullptr)},
            {"fitted_scale", Nullable(r.fitted_scale)},
            {"share_outside_identified_ranges", Nullable(r.share_outside_identified_ranges)}};
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

api::Result<ComparisonRequest> ComparisonRequestFromJson(const json& j) {
  return Parse<ComparisonRequest>([&] {
    ComparisonRequest r;
    Fields f(j, "");
    const json* pairs = f.Get("pairs");
    if (pairs == nullptr) Fail("pairs", "required");
    if (!pairs->is_array()) Fail("pairs", "must be an array of pairs");
    for (std::size_t i = 0; i < pairs->size(); ++i) {
      const std::string path = "pairs[" + std::to_string(i) + "]";
      Fields p((*pairs)[i], path);
      ComparisonPair pair;
      const json* a = p.Get("a_parameter_set_id");
      if (a == nullptr) Fail(p.Path("a_parameter_set_id"), "required");
      pair.a_parameter_set_id = Id(*a, p.Path("a_parameter_set_id"));
      const json* b = p.Get("b_parameter_set_id");
      if (b == nullptr) Fail(p.Path("b_parameter_set_id"), "required");
      pair.b_parameter_set_id = Id(*b, p.Path("b_parameter_set_id"));
      const json* t = p.Get("trial_ids");
      if (t == nullptr) Fail(p.Path("trial_ids"), "required");
      pair.trial_ids = Ids(*t, p.Path("trial_ids"));
      p.Done();
      r.pairs.push_back(std::move(pair));
    }
    if (const json* v = f.Get("metric")) r.metric = Text(*v, "metric");
    if (const json* v = f.Get("confidence")) r.confidence = Number(*v, "confidence");
    f.Done();
    if (api::Status s = ValidateComparisonRequest(r); !s.ok()) throw ParseError{s};
    return r;
  });
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
  const model::PairedTTestResult& t = r.test;
  return {{"metric", r.metric},
          {"unit", r.unit},
          {"pairs", pairs},
          {"t_test",
           {{"mean_difference", t.mean_difference},
            {"sd_difference", t.sd_difference},
            {"n", t.n},
            {"t", t.t},
            {"df", t.df},
            {"p_value", t.p_value},
            {"confidence", t.confidence},
            {"t_critical", t.t_critical},
            {"significant", t.significant}}}};
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
