#include "api/analysis_requests.h"

#include <array>
#include <cmath>
#include <utility>

#include "api/json_fields.h"
#include "api/name_table.h"
#include "model/identify_rapid.h"

namespace fesbench::api {
namespace {

using nlohmann::json;

constexpr NameTable<PredictionMode, 2> kPredictionModes(
    {{{PredictionMode::kFreeSwing, "free_swing"}, {PredictionMode::kIsometric, "isometric"}}},
    "free_swing");

// The api's name table of a model enumeration: the model's own names, so
// the wire, the stored provenance and the CLI spell each value one way.
template <typename Enum, std::size_t N>
NameTable<Enum, N> TableOf(const std::array<Enum, N>& values, std::string_view (*name)(Enum)) {
  std::array<typename NameTable<Enum, N>::Entry, N> entries{};
  for (std::size_t i = 0; i < N; ++i) entries[i] = {values[i], name(values[i])};
  return NameTable<Enum, N>(entries, "unknown");
}

const auto& IdentificationMethods() {
  static const auto table =
      TableOf(model::kIdentificationMethods, &model::IdentificationMethodName);
  return table;
}
const auto& IrcMethods() {
  static const auto table = TableOf(model::kIrcMethods, &model::IrcMethodName);
  return table;
}
const auto& PassiveMethods() {
  static const auto table = TableOf(model::kPassiveMethods, &model::PassiveMethodName);
  return table;
}
const auto& PoleMethods() {
  static const auto table = TableOf(model::kPoleMethods, &model::PoleMethodName);
  return table;
}

// "a, b or c".
std::string OneOf(const std::vector<std::string>& names) {
  std::string text;
  for (std::size_t i = 0; i < names.size(); ++i) {
    text += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + names[i];
  }
  return text;
}

// The choice named at `key`: nullopt when absent, or when the name is none
// of the table's (then recorded in `fields`, "must be a, b or c").
template <typename Enum, std::size_t N>
std::optional<Enum> ReadChoice(JsonFields& fields, std::string_view key,
                               const NameTable<Enum, N>& table) {
  const std::optional<std::string> name = fields.String(key, false);
  if (!name) return std::nullopt;
  const std::optional<Enum> value = table.Parse(*name);
  if (!value) fields.Fail(key, "must be " + OneOf(table.Names()));
  return value;
}

std::string Indexed(const std::string& path, std::size_t i) {
  return path + "[" + std::to_string(i) + "]";
}

// A breakpoint spec at `path`: a count (2–101) or an array of finite numbers.
Result<model::BreakpointSpec> BreakpointsFromJson(const json& value, const std::string& path) {
  model::BreakpointSpec spec;
  if (value.is_number_integer()) {
    const auto count = value.get<std::int64_t>();
    if (count < 2 || count > 101) {
      return Status::InvalidArgument("must be 2–101 breakpoints, got " + value.dump(), path);
    }
    spec.count = static_cast<int>(count);
    return spec;
  }
  if (!value.is_array()) {
    return Status::InvalidArgument("must be a count (integer) or an array of breakpoints", path);
  }
  for (std::size_t i = 0; i < value.size(); ++i) {
    if (!value[i].is_number() || !std::isfinite(value[i].get<double>())) {
      return Status::InvalidArgument("must be a finite number, got " + value[i].dump(),
                                     Indexed(path, i));
    }
    spec.explicit_x.push_back(value[i].get<double>());
  }
  return spec;
}

json BreakpointsToJson(const model::BreakpointSpec& spec) {
  return spec.explicit_x.empty() ? json(spec.count) : json(spec.explicit_x);
}

Status ReadBreakpoints(const json& object, const std::string& path,
                       IdentificationBreakpoints& out) {
  JsonFields fields(object, path);
  const std::pair<const char*, std::optional<model::BreakpointSpec>*> kCurves[] = {
      {"passive_angle", &out.passive_angle},
      {"passive_velocity", &out.passive_velocity},
      {"active_angle", &out.active_angle},
      {"active_velocity", &out.active_velocity},
  };
  for (const auto& [key, spec] : kCurves) {
    if (const json* value = fields.Any(key, false)) {
      Result<model::BreakpointSpec> read = BreakpointsFromJson(*value, fields.PathOf(key));
      if (!read.ok()) return read.status();
      *spec = *std::move(read);
    }
  }
  return fields.Finish();
}

// Model variant names (model::ModelKindName), each parsed once.
Result<std::vector<model::ModelKind>> ModelKinds(const json& value, const std::string& path) {
  if (!value.is_array()) return Status::InvalidArgument("must be an array of names", path);
  std::vector<model::ModelKind> kinds;
  for (std::size_t i = 0; i < value.size(); ++i) {
    if (!value[i].is_string()) {
      return Status::InvalidArgument("must be a string, got " + value[i].dump(), Indexed(path, i));
    }
    const std::string name = value[i].get<std::string>();
    const std::optional<model::ModelKind> kind = model::ParseModelKind(name);
    if (!kind) {
      std::vector<std::string> known;
      for (model::ModelKind k : model::AllModelKinds()) known.emplace_back(model::ModelKindName(k));
      std::string list;
      for (std::size_t k = 0; k < known.size(); ++k) list += (k ? ", " : "") + known[k];
      return Status::InvalidArgument("unknown model \"" + name.substr(0, 40) + "\" (" + list + ")",
                                     Indexed(path, i));
    }
    kinds.push_back(*kind);
  }
  return kinds;
}

Result<StimulusSpec> StimulusFromJson(const json& object, const std::string& path) {
  JsonFields fields(object, path);
  StimulusSpec spec;
  spec.generator = fields.String("generator", true).value_or("");
  if (const json* params = fields.Object("params", false)) {
    for (const auto& [key, value] : params->items()) {
      if (!value.is_number() || !std::isfinite(value.get<double>())) {
        return Status::InvalidArgument("must be a finite number, got " + value.dump(),
                                       fields.PathOf("params") + "." + key);
      }
      spec.params[key] = value.get<double>();
    }
  }
  if (Status s = fields.Finish(); !s.ok()) return s;
  return spec;
}

}  // namespace

std::vector<std::string> IdentificationMethodNames() { return IdentificationMethods().Names(); }
std::vector<std::string> IrcMethodNames() { return IrcMethods().Names(); }
std::vector<std::string> PassiveMethodNames() { return PassiveMethods().Names(); }
std::vector<std::string> PoleMethodNames() { return PoleMethods().Names(); }

std::string_view PredictionModeName(PredictionMode mode) { return kPredictionModes.Name(mode); }

std::optional<PredictionMode> ParsePredictionMode(std::string_view name) {
  return kPredictionModes.Parse(name);
}

Result<IdentificationRequest> IdentificationRequestFromJson(const json& body) {
  using model::IdentificationMethod;
  using model::IrcMethod;
  using model::PassiveMethod;
  IdentificationRequest r;
  JsonFields fields(body);
  r.session_id = fields.Integer("session_id", false, 1);
  r.trial_ids = fields.IdList("trial_ids", false).value_or(std::vector<std::int64_t>{});
  r.method = ReadChoice(fields, "method", IdentificationMethods()).value_or(r.method);
  const std::optional<IrcMethod> irc_method = ReadChoice(fields, "irc_method", IrcMethods());
  const std::optional<PassiveMethod> passive_method =
      ReadChoice(fields, "passive_method", PassiveMethods());
  const std::optional<std::int64_t> contraction_order =
      fields.Integer("contraction_order", false, 0, 3);
  const std::optional<model::PoleMethod> pole_method =
      ReadChoice(fields, "pole_method", PoleMethods());
  if (!fields.ok()) return fields.status();
  // The rapid routine (§7.4.1) fits with its own methods (docs/API.md,
  // Parameter sets: ramp_deconvolution_ideal, free swing): another method named with
  // it would be ignored, so it is refused instead.
  // Method passive fits the passive block alone, in free swing (docs/MODEL.md).
  if (r.method == IdentificationMethod::kPassive) {
    for (const auto& [given, key] : {std::pair{irc_method.has_value(), "irc_method"},
                                     std::pair{contraction_order.has_value(), "contraction_order"},
                                     std::pair{pole_method.has_value(), "pole_method"}}) {
      if (given) {
        return Status::InvalidArgument(
            std::string("method passive fits no stimulated trial; ") + key + " needs method thesis",
            key);
      }
    }
    if (passive_method && *passive_method != PassiveMethod::kFreeSwing) {
      return Status::InvalidArgument(
          "method passive fits the passive curves in free swing; passive_method " +
              std::string(PassiveMethods().Name(*passive_method)) + " needs method thesis",
          "passive_method");
    }
  }
  if (r.method == IdentificationMethod::kRapid) {
    if (irc_method && *irc_method != model::kRapidIrcMethod) {
      return Status::InvalidArgument("method rapid fits the IRC by " +
                                         std::string(IrcMethods().Name(model::kRapidIrcMethod)) +
                                         "; irc_method " +
                                         std::string(IrcMethods().Name(*irc_method)) +
                                         " needs method thesis",
                                     "irc_method");
    }
    if (passive_method && *passive_method != PassiveMethod::kFreeSwing) {
      return Status::InvalidArgument(
          "method rapid fits the passive curves in free swing; passive_method " +
              std::string(PassiveMethods().Name(*passive_method)) + " needs method thesis",
          "passive_method");
    }
    if (contraction_order) {
      return Status::InvalidArgument(
          "method rapid does not take contraction_order (it is a method thesis option)",
          "contraction_order");
    }
    if (pole_method) {
      return Status::InvalidArgument(
          "method rapid does not take pole_method (it is a method thesis option)", "pole_method");
    }
  }
  r.irc_method = irc_method.value_or(r.irc_method);
  r.passive_method = passive_method.value_or(
      r.method == IdentificationMethod::kThesis ? r.passive_method : PassiveMethod::kFreeSwing);
  r.contraction_order = static_cast<int>(contraction_order.value_or(3));
  r.pole_method = pole_method.value_or(r.pole_method);
  if (const json* models = fields.Any("models", false)) {
    Result<std::vector<model::ModelKind>> kinds = ModelKinds(*models, fields.PathOf("models"));
    if (!kinds.ok()) return kinds.status();
    r.models = *std::move(kinds);
  }
  if (const json* breakpoints = fields.Object("breakpoints", false)) {
    Status s = ReadBreakpoints(*breakpoints, fields.PathOf("breakpoints"), r.breakpoints);
    if (!s.ok()) return s;
  }
  r.inertia_kgm2 = fields.Number("inertia_kgm2", false);
  r.gravity_moment_nm = fields.Number("gravity_moment_nm", false);
  if (r.gravity_moment_nm && r.method != IdentificationMethod::kPassive) {
    return Status::InvalidArgument(
        "only method passive takes gravity_moment_nm (the others need no gravity moment)",
        "gravity_moment_nm");
  }
  r.torque_angle_parameter_set_id = fields.Integer("torque_angle_parameter_set_id", false, 1);
  if (Status s = fields.Finish(); !s.ok()) return s;
  return r;
}

json IdentificationRequestToJson(const IdentificationRequest& r) {
  json models = json::array();
  for (model::ModelKind kind : r.models) models.push_back(model::ModelKindName(kind));
  json j = {{"method", IdentificationMethods().Name(r.method)}, {"models", models}};
  // Methods rapid and passive take none of the thesis methods (their own are fixed).
  if (r.method == model::IdentificationMethod::kThesis) {
    j["irc_method"] = IrcMethods().Name(r.irc_method);
    j["passive_method"] = PassiveMethods().Name(r.passive_method);
    j["contraction_order"] = r.contraction_order;
    j["pole_method"] = PoleMethods().Name(r.pole_method);
  }
  if (r.session_id) j["session_id"] = *r.session_id;
  if (!r.trial_ids.empty()) j["trial_ids"] = r.trial_ids;
  json breakpoints = json::object();
  const std::pair<const char*, const std::optional<model::BreakpointSpec>*> kCurves[] = {
      {"passive_angle", &r.breakpoints.passive_angle},
      {"passive_velocity", &r.breakpoints.passive_velocity},
      {"active_angle", &r.breakpoints.active_angle},
      {"active_velocity", &r.breakpoints.active_velocity},
  };
  for (const auto& [key, spec] : kCurves) {
    if (*spec) breakpoints[key] = BreakpointsToJson(**spec);
  }
  j["breakpoints"] = breakpoints;
  if (r.inertia_kgm2) j["inertia_kgm2"] = *r.inertia_kgm2;
  if (r.gravity_moment_nm) j["gravity_moment_nm"] = *r.gravity_moment_nm;
  if (r.torque_angle_parameter_set_id) {
    j["torque_angle_parameter_set_id"] = *r.torque_angle_parameter_set_id;
  }
  return j;
}

Result<PredictionRequest> PredictionRequestFromJson(const json& body) {
  PredictionRequest r;
  JsonFields fields(body);
  r.parameter_set_id = fields.Integer("parameter_set_id", true, 1).value_or(0);
  r.trial_id = fields.Integer("trial_id", false, 1);
  if (const json* stimulus = fields.Object("stimulus", false)) {
    Result<StimulusSpec> spec = StimulusFromJson(*stimulus, fields.PathOf("stimulus"));
    if (!spec.ok()) return spec.status();
    r.stimulus = *std::move(spec);
  }
  if (std::optional<std::string> mode = fields.String("mode", false)) {
    r.mode = ParsePredictionMode(*mode);
    if (!r.mode) return Status::InvalidArgument("must be free_swing or isometric", "mode");
  }
  r.initial_angle_deg = fields.Number("initial_angle_deg", false);
  r.initial_velocity_deg_s = fields.Number("initial_velocity_deg_s", false).value_or(0.0);
  r.duration_s = fields.Number("duration_s", false);
  r.fit_scale = fields.Bool("fit_scale", false).value_or(false);
  if (Status s = fields.Finish(); !s.ok()) return s;
  return r;
}

json PredictionRequestToJson(const PredictionRequest& r) {
  json j = {{"parameter_set_id", r.parameter_set_id}};
  if (r.trial_id) j["trial_id"] = *r.trial_id;
  if (r.stimulus) {
    json params = json::object();
    for (const auto& [key, value] : r.stimulus->params) params[key] = value;
    j["stimulus"] = {{"generator", r.stimulus->generator}, {"params", params}};
  }
  if (r.mode) j["mode"] = PredictionModeName(*r.mode);
  if (r.initial_angle_deg) j["initial_angle_deg"] = *r.initial_angle_deg;
  if (r.stimulus) j["initial_velocity_deg_s"] = r.initial_velocity_deg_s;
  if (r.duration_s) j["duration_s"] = *r.duration_s;
  if (r.fit_scale) j["fit_scale"] = true;
  return j;
}

Result<ComparisonRequest> ComparisonRequestFromJson(const json& body) {
  ComparisonRequest r;
  JsonFields fields(body);
  if (const json* pairs = fields.Any("pairs", true)) {
    if (!pairs->is_array()) return Status::InvalidArgument("must be an array of pairs", "pairs");
    for (std::size_t i = 0; i < pairs->size(); ++i) {
      JsonFields pair_fields((*pairs)[i], Indexed("pairs", i));
      ComparisonPair pair;
      pair.a_parameter_set_id = pair_fields.Integer("a_parameter_set_id", true, 1).value_or(0);
      pair.b_parameter_set_id = pair_fields.Integer("b_parameter_set_id", true, 1).value_or(0);
      pair.trial_ids = pair_fields.IdList("trial_ids", true).value_or(std::vector<std::int64_t>{});
      if (Status s = pair_fields.Finish(); !s.ok()) return s;
      r.pairs.push_back(std::move(pair));
    }
  }
  r.metric = fields.String("metric", false).value_or(r.metric);
  r.confidence = fields.Number("confidence", false).value_or(r.confidence);
  if (Status s = fields.Finish(); !s.ok()) return s;
  return r;
}

json ComparisonRequestToJson(const ComparisonRequest& r) {
  json pairs = json::array();
  for (const ComparisonPair& p : r.pairs) {
    pairs.push_back({{"a_parameter_set_id", p.a_parameter_set_id},
                     {"b_parameter_set_id", p.b_parameter_set_id},
                     {"trial_ids", p.trial_ids}});
  }
  return {{"pairs", pairs}, {"metric", r.metric}, {"confidence", r.confidence}};
}

}  // namespace fesbench::api
