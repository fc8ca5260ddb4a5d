#include "api/parameter_set_json.h"

#include <cmath>
#include <initializer_list>
#include <limits>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace fesbench::api {
namespace {

using model::ModelKind;
using model::PiecewiseLinear;
using nlohmann::json;

// Which optional parts each model variant evaluates (docs/MODEL.md, "Model variants"): a part a
// variant uses is required on input; one it ignores may be omitted.
struct VariantNeeds {
  bool passive_torque_angle = true;    // PWL τ_pta (parametric uses Eq. 7.3).
  bool active_torque_angle = true;     // PWL f_ata.
  bool active_torque_velocity = true;  // PWL f_atv.
  bool single_segment = false;
  bool parametric = false;
};

VariantNeeds NeedsOf(ModelKind kind) {
  switch (kind) {
    case ModelKind::kFull:
      return {};
    case ModelKind::kTorqueGenerator:
      return {true, false, false, false, false};
    case ModelKind::kSingleSegment:
      return {true, false, false, true, false};
    case ModelKind::kStaticGainPwlVelocity:
      return {true, false, true, false, false};
    case ModelKind::kParametric:
      return {false, false, false, false, true};
  }
  return {};
}

json CurveToJson(const PiecewiseLinear& curve, const char* x_key, const char* y_key) {
  return {{x_key, curve.x()}, {y_key, curve.y()}};
}

// Walks a JSON document, reporting the first problem with its dotted path.
// Each Read* returns false after recording the failure in status_.
class Reader {
 public:
  const Status& status() const { return status_; }

  bool Fail(std::string message, std::string path) {
    status_ = Status::InvalidArgument(std::move(message), std::move(path));
    return false;
  }

  static std::string Join(std::string_view parent, std::string_view key) {
    return parent.empty() ? std::string(key) : std::string(parent) + "." + std::string(key);
  }

  bool RequireObject(const json& j, const std::string& path) {
    return j.is_object() || Fail("must be an object", path);
  }

  // Rejects keys of a section that are not in `known` (catches typos).
  bool OnlyKeys(const json& obj, const std::string& path,
                std::initializer_list<std::string_view> known) {
    for (auto it = obj.begin(); it != obj.end(); ++it) {
      bool found = false;
      for (std::string_view k : known) found = found || it.key() == k;
      if (!found) return Fail("unknown field", Join(path, it.key()));
    }
    return true;
  }

  // The member `key` of obj, or nullptr (failing if `required`).
  const json* Member(const json& obj, std::string_view key, const std::string& path,
                     bool required) {
    const auto it = obj.find(key);
    if (it == obj.end() || (it->is_null() && required)) {
      if (required) Fail("missing required field", Join(path, key));
      return nullptr;
    }
    return &*it;
  }

  bool ReadFinite(const json& j, const std::string& path, double& out) {
    if (!j.is_number()) return Fail("must be a number", path);
    out = j.get<double>();
    if (!std::isfinite(out)) return Fail("must be finite (not NaN or infinite)", path);
    return true;
  }

  bool ReadNumber(const json& obj, std::string_view key, const std::string& parent, double& out) {
    const json* j = Member(obj, key, parent, true);
    return j != nullptr && ReadFinite(*j, Join(parent, key), out);
  }

  bool ReadNumberArray(const json& obj, std::string_view key, const std::string& parent,
                       std::vector<double>& out) {
    const std::string path = Join(parent, key);
    const json* j = Member(obj, key, parent, true);
    if (j == nullptr) return false;
    if (!j->is_array()) return Fail("must be an array of numbers", path);
    if (j->empty()) return Fail("must not be empty", path);
    out.clear();
    out.reserve(j->size());
    for (std::size_t i = 0; i < j->size(); ++i) {
      double v = 0.0;
      if (!ReadFinite((*j)[i], path + "[" + std::to_string(i) + "]", v)) return false;
      out.push_back(v);
    }
    return true;
  }

  bool ReadString(const json& obj, std::string_view key, const std::string& parent,
                  std::string& out) {
    const json* j = Member(obj, key, parent, false);
    if (j == nullptr) return true;
    if (!j->is_string()) return Fail("must be a string", Join(parent, key));
    out = j->get<std::string>();
    return true;
  }

  // A PWL curve {x_key: [...], y_key: [...]}: x strictly increasing, equal
  // lengths, all finite; y within [y_min, y_max].
  bool ReadCurve(const json& obj, std::string_view key, const std::string& parent,
                 const char* x_key, const char* y_key, double y_min, double y_max,
                 PiecewiseLinear& out) {
    const std::string path = Join(parent, key);
    const json* j = Member(obj, key, parent, true);
    if (j == nullptr || !RequireObject(*j, path) || !OnlyKeys(*j, path, {x_key, y_key})) {
      return false;
    }
    std::vector<double> x, y;
    if (!ReadNumberArray(*j, x_key, path, x) || !ReadNumberArray(*j, y_key, path, y)) return false;
    const std::string x_path = Join(path, x_key);
    const std::string y_path = Join(path, y_key);
    if (x.size() != y.size()) {
      return Fail("has " + std::to_string(y.size()) + " values but " + x_key + " has " +
                      std::to_string(x.size()),
                  y_path);
    }
    for (std::size_t i = 1; i < x.size(); ++i) {
      if (!(x[i] > x[i - 1])) {
        return Fail("breakpoints must be strictly increasing",
                    x_path + "[" + std::to_string(i) + "]");
      }
    }
    for (std::size_t i = 0; i < y.size(); ++i) {
      if (y[i] < y_min || y[i] > y_max) {
        std::string range = y_max == kUnbounded
                                ? "must be >= " + Number(y_min)
                                : "must be in [" + Number(y_min) + ", " + Number(y_max) + "]";
        return Fail(std::move(range), y_path + "[" + std::to_string(i) + "]");
      }
    }
    out = PiecewiseLinear(std::move(x), std::move(y));
    return true;
  }

  static constexpr double kUnbounded = std::numeric_limits<double>::infinity();

 private:
  static std::string Number(double v) {
    json j = v;
    return j.dump();
  }

  Status status_;
};

bool ReadProvenance(Reader& r, const json& j, model::Provenance& out) {
  const std::string path = "provenance";
  if (!r.RequireObject(j, path)) return false;
  // Provenance is descriptive metadata: unknown keys are ignored so that
  // newer writers can add to it.
  if (!r.ReadString(j, "irc_method", path, out.irc_method) ||
      !r.ReadString(j, "passive_method", path, out.passive_method) ||
      !r.ReadString(j, "active_method", path, out.active_method) ||
      !r.ReadString(j, "inertia_method", path, out.inertia_method) ||
      !r.ReadString(j, "software_version", path, out.software_version)) {
    return false;
  }
  if (const json* id = r.Member(j, "active_trial_id", path, false); id && !id->is_null()) {
    if (!id->is_number_integer()) return r.Fail("must be an integer", path + ".active_trial_id");
    out.active_trial_id = id->get<std::int64_t>();
  }
  if (const json* ids = r.Member(j, "trial_ids", path, false); ids && !ids->is_null()) {
    if (!ids->is_array()) return r.Fail("must be an array of integers", path + ".trial_ids");
    for (std::size_t i = 0; i < ids->size(); ++i) {
      if (!(*ids)[i].is_number_integer()) {
        return r.Fail("must be an integer", path + ".trial_ids[" + std::to_string(i) + "]");
      }
      out.trial_ids.push_back((*ids)[i].get<std::int64_t>());
    }
  }
  if (const json* rms = r.Member(j, "fit_rms", path, false); rms && !rms->is_null()) {
    if (!rms->is_object()) return r.Fail("must be an object of numbers", path + ".fit_rms");
    for (auto it = rms->begin(); it != rms->end(); ++it) {
      double v = 0.0;
      if (!r.ReadFinite(it.value(), path + ".fit_rms." + it.key(), v)) return false;
      out.fit_rms[it.key()] = v;
    }
  }
  // Ranges the curves were identified over: {"tau_pta": [lo, hi], …}.
  for (const auto& [key, target] :
       {std::pair{"identified_range_deg", &out.identified_range_deg},
        std::pair{"identified_range_deg_s", &out.identified_range_deg_s}}) {
    const json* ranges = r.Member(j, key, path, false);
    if (ranges == nullptr || ranges->is_null()) continue;
    const std::string where = path + "." + key;
    if (!ranges->is_object()) return r.Fail("must be an object of [lo, hi] pairs", where);
    for (auto it = ranges->begin(); it != ranges->end(); ++it) {
      const std::string field = where + "." + it.key();
      const json& pair = it.value();
      if (!pair.is_array() || pair.size() != 2) return r.Fail("must be [lo, hi]", field);
      model::CurveRange range;
      if (!r.ReadFinite(pair[0], field + "[0]", range.lo) ||
          !r.ReadFinite(pair[1], field + "[1]", range.hi)) {
        return false;
      }
      if (range.lo > range.hi) return r.Fail("lo must not exceed hi", field);
      (*target)[it.key()] = range;
    }
  }
  if (const json* w = r.Member(j, "warnings", path, false); w && !w->is_null()) {
    if (!w->is_array()) return r.Fail("must be an array of strings", path + ".warnings");
    for (std::size_t i = 0; i < w->size(); ++i) {
      if (!(*w)[i].is_string()) {
        return r.Fail("must be a string", path + ".warnings[" + std::to_string(i) + "]");
      }
      out.warnings.push_back((*w)[i].get<std::string>());
    }
  }
  return true;
}

bool Read(Reader& r, const json& j, model::ParameterSet& p) {
  constexpr double kInf = Reader::kUnbounded;
  if (!r.RequireObject(j, "")) return false;
  // Top-level keys other than the sections below are ignored, so that a
  // server resource may carry its own metadata (id, version, …) beside them.

  // "model"
  const json* model = r.Member(j, "model", "", true);
  if (model == nullptr) return false;
  if (!model->is_string()) return r.Fail("must be a string", "model");
  const std::optional<ModelKind> kind = model::ParseModelKind(model->get<std::string>());
  if (!kind) {
    std::string names;
    for (ModelKind k : model::AllModelKinds()) {
      names += (names.empty() ? "" : ", ") + std::string(model::ModelKindName(k));
    }
    return r.Fail("unknown model '" + model->get<std::string>() + "' (known: " + names + ")",
                  "model");
  }
  p.model = *kind;
  const VariantNeeds needs = NeedsOf(p.model);

  // "irc": R(u), activation in [0, 1] (§3.2).
  if (!r.ReadCurve(j, "irc", "", "stim_ma", "activation", 0.0, 1.0, p.irc)) return false;

  // "contraction": H_n(s) = a^n / (s + a)^n, n = 2 or 3 (Eqs. 4.1–4.4).
  const json* contraction = r.Member(j, "contraction", "", true);
  if (contraction == nullptr || !r.RequireObject(*contraction, "contraction") ||
      !r.OnlyKeys(*contraction, "contraction", {"order", "pole_per_s"})) {
    return false;
  }
  const json* order = r.Member(*contraction, "order", "contraction", true);
  if (order == nullptr) return false;
  if (!order->is_number_integer())
    return r.Fail("must be an integer (2 or 3)", "contraction.order");
  const std::int64_t n = order->get<std::int64_t>();
  if (n != 2 && n != 3) return r.Fail("must be 2 or 3", "contraction.order");
  p.contraction.order = static_cast<int>(n);
  if (!r.ReadNumber(*contraction, "pole_per_s", "contraction", p.contraction.pole_per_s)) {
    return false;
  }
  if (!(p.contraction.pole_per_s > 0.0)) return r.Fail("must be > 0", "contraction.pole_per_s");

  // "passive" (§4.2).
  const json* passive = r.Member(j, "passive", "", true);
  if (passive == nullptr || !r.RequireObject(*passive, "passive") ||
      !r.OnlyKeys(*passive, "passive", {"inertia_kgm2", "torque_angle", "torque_velocity"})) {
    return false;
  }
  if (!r.ReadNumber(*passive, "inertia_kgm2", "passive", p.passive.inertia_kgm2)) return false;
  if (!(p.passive.inertia_kgm2 > 0.0)) return r.Fail("must be > 0", "passive.inertia_kgm2");
  if ((needs.passive_torque_angle || passive->contains("torque_angle")) &&
      !r.ReadCurve(*passive, "torque_angle", "passive", "angle_deg", "torque_nm", -kInf, kInf,
                   p.passive.torque_angle)) {
    return false;
  }
  if (!r.ReadCurve(*passive, "torque_velocity", "passive", "velocity_deg_s", "torque_nm", -kInf,
                   kInf, p.passive.torque_velocity)) {
    return false;
  }

  // "active" (Eq. 3.16).
  const json* active = r.Member(j, "active", "", true);
  if (active == nullptr || !r.RequireObject(*active, "active") ||
      !r.OnlyKeys(*active, "active", {"torque_scale_nm", "torque_angle", "torque_velocity"})) {
    return false;
  }
  if (!r.ReadNumber(*active, "torque_scale_nm", "active", p.active.torque_scale_nm)) return false;
  if (p.active.torque_scale_nm < 0.0) return r.Fail("must be >= 0", "active.torque_scale_nm");
  if ((needs.active_torque_angle || active->contains("torque_angle")) &&
      !r.ReadCurve(*active, "torque_angle", "active", "angle_deg", "gain", 0.0, kInf,
                   p.active.torque_angle)) {
    return false;
  }
  if ((needs.active_torque_velocity || active->contains("torque_velocity")) &&
      !r.ReadCurve(*active, "torque_velocity", "active", "velocity_deg_s", "gain", 0.0, kInf,
                   p.active.torque_velocity)) {
    return false;
  }

  // "single_segment" (Eqs. 5.1–5.2).
  if (needs.single_segment || j.contains("single_segment")) {
    const json* s = r.Member(j, "single_segment", "", true);
    if (s == nullptr || !r.RequireObject(*s, "single_segment") ||
        !r.OnlyKeys(*s, "single_segment", {"a", "b", "c", "d"}) ||
        !r.ReadNumber(*s, "a", "single_segment", p.single_segment.a) ||
        !r.ReadNumber(*s, "b", "single_segment", p.single_segment.b) ||
        !r.ReadNumber(*s, "c", "single_segment", p.single_segment.c) ||
        !r.ReadNumber(*s, "d", "single_segment", p.single_segment.d)) {
      return false;
    }
  }

  // "parametric" (§7.4.4, Eq. 7.3).
  if (needs.parametric || j.contains("parametric")) {
    const json* s = r.Member(j, "parametric", "", true);
    const std::string path = "parametric";
    model::ParametricParams& q = p.parametric;
    if (s == nullptr || !r.RequireObject(*s, path) ||
        !r.OnlyKeys(*s, path,
                    {"mgl_nm", "k1_nm", "k2_per_rad", "offset_nm", "ata_peak_deg", "ata_width_deg",
                     "atv_slope_neg_per_deg_s", "atv_slope_pos_per_deg_s"}) ||
        !r.ReadNumber(*s, "mgl_nm", path, q.mgl_nm) || !r.ReadNumber(*s, "k1_nm", path, q.k1_nm) ||
        !r.ReadNumber(*s, "k2_per_rad", path, q.k2_per_rad) ||
        !r.ReadNumber(*s, "offset_nm", path, q.offset_nm) ||
        !r.ReadNumber(*s, "ata_peak_deg", path, q.ata_peak_deg) ||
        !r.ReadNumber(*s, "ata_width_deg", path, q.ata_width_deg) ||
        !r.ReadNumber(*s, "atv_slope_neg_per_deg_s", path, q.atv_slope_neg_per_deg_s) ||
        !r.ReadNumber(*s, "atv_slope_pos_per_deg_s", path, q.atv_slope_pos_per_deg_s)) {
      return false;
    }
    if (!(q.ata_width_deg > 0.0)) return r.Fail("must be > 0", "parametric.ata_width_deg");
  }

  // "provenance" (optional).
  if (const json* prov = r.Member(j, "provenance", "", false); prov && !prov->is_null()) {
    if (!ReadProvenance(r, *prov, p.provenance)) return false;
  }
  return true;
}

}  // namespace

json ParameterSetToJson(const model::ParameterSet& p) {
  json j = json::object();
  j["model"] = std::string(model::ModelKindName(p.model));
  j["irc"] = CurveToJson(p.irc, "stim_ma", "activation");
  j["contraction"] = {{"order", p.contraction.order}, {"pole_per_s", p.contraction.pole_per_s}};

  json passive = {{"inertia_kgm2", p.passive.inertia_kgm2}};
  if (!p.passive.torque_angle.empty()) {
    passive["torque_angle"] = CurveToJson(p.passive.torque_angle, "angle_deg", "torque_nm");
  }
  if (!p.passive.torque_velocity.empty()) {
    passive["torque_velocity"] =
        CurveToJson(p.passive.torque_velocity, "velocity_deg_s", "torque_nm");
  }
  j["passive"] = std::move(passive);

  json active = {{"torque_scale_nm", p.active.torque_scale_nm}};
  if (!p.active.torque_angle.empty()) {
    active["torque_angle"] = CurveToJson(p.active.torque_angle, "angle_deg", "gain");
  }
  if (!p.active.torque_velocity.empty()) {
    active["torque_velocity"] = CurveToJson(p.active.torque_velocity, "velocity_deg_s", "gain");
  }
  j["active"] = std::move(active);

  // Variant sections: written when the variant uses them or when they differ
  // from their defaults, so that the round trip is lossless either way.
  const VariantNeeds needs = NeedsOf(p.model);
  if (needs.single_segment || p.single_segment != model::SingleSegmentParams{}) {
    const auto& s = p.single_segment;
    j["single_segment"] = {{"a", s.a}, {"b", s.b}, {"c", s.c}, {"d", s.d}};
  }
  if (needs.parametric || p.parametric != model::ParametricParams{}) {
    const auto& q = p.parametric;
    j["parametric"] = {{"mgl_nm", q.mgl_nm},
                       {"k1_nm", q.k1_nm},
                       {"k2_per_rad", q.k2_per_rad},
                       {"offset_nm", q.offset_nm},
                       {"ata_peak_deg", q.ata_peak_deg},
                       {"ata_width_deg", q.ata_width_deg},
                       {"atv_slope_neg_per_deg_s", q.atv_slope_neg_per_deg_s},
                       {"atv_slope_pos_per_deg_s", q.atv_slope_pos_per_deg_s}};
  }

  const model::Provenance& prov = p.provenance;
  json fit_rms = json::object();
  for (const auto& [key, value] : prov.fit_rms) fit_rms[key] = value;
  const auto ranges = [](const std::map<std::string, model::CurveRange>& m) {
    json o = json::object();
    for (const auto& [key, range] : m) o[key] = json::array({range.lo, range.hi});
    return o;
  };
  j["provenance"] = {
      {"irc_method", prov.irc_method},
      {"passive_method", prov.passive_method},
      {"active_method", prov.active_method},
      {"inertia_method", prov.inertia_method},
      {"active_trial_id", prov.active_trial_id ? json(*prov.active_trial_id) : json(nullptr)},
      {"trial_ids", prov.trial_ids},
      {"fit_rms", std::move(fit_rms)},
      {"warnings", prov.warnings},
      {"software_version", prov.software_version},
      {"identified_range_deg", ranges(prov.identified_range_deg)},
      {"identified_range_deg_s", ranges(prov.identified_range_deg_s)},
  };
  return j;
}

Result<model::ParameterSet> ParameterSetFromJson(const json& j) {
  Reader reader;
  model::ParameterSet p;
  // Curves start empty: a part the variant ignores and the JSON omits stays
  // empty.
  if (!Read(reader, j, p)) return reader.status();
  return p;
}

}  // namespace fesbench::api
