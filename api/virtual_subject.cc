#include "api/virtual_subject.h"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <string_view>

#include "api/model_call.h"
#include "api/parameter_set_json.h"
#include "model/contraction.h"
#include "model/joint_model.h"

namespace fesbench::api {
namespace {

using nlohmann::json;
constexpr double kInf = std::numeric_limits<double>::infinity();

// A numeric field with its valid range; `lo_open` excludes the lower bound.
template <class T>
struct NumberField {
  const char* key;
  double T::*member;
  double lo;
  double hi;
  bool lo_open;
};

const NumberField<Fidelity> kFidelityNumbers[] = {
    {"twitch_variation", &Fidelity::twitch_variation, 0.0, 1.0, false},
    {"series_stiffness_nm_per_deg", &Fidelity::series_stiffness_nm_per_deg, 0.0, kInf, false},
    {"hysteresis_nm", &Fidelity::hysteresis_nm, 0.0, kInf, false},
    {"hysteresis_angle_deg", &Fidelity::hysteresis_angle_deg, 0.0, kInf, true},
    {"static_friction_nm", &Fidelity::static_friction_nm, 0.0, kInf, false},
    {"friction_velocity_deg_s", &Fidelity::friction_velocity_deg_s, 0.0, kInf, true},
    {"fatigue_rate_per_s", &Fidelity::fatigue_rate_per_s, 0.0, kInf, false},
    {"fatigue_recovery_s", &Fidelity::fatigue_recovery_s, 0.0, kInf, true},
    {"potentiation_max", &Fidelity::potentiation_max, 0.0, kInf, false},
    {"potentiation_rate_per_s", &Fidelity::potentiation_rate_per_s, 0.0, kInf, false},
    {"potentiation_decay_s", &Fidelity::potentiation_decay_s, 0.0, kInf, true},
    {"pot_nonlinearity", &Fidelity::pot_nonlinearity, 0.0, 0.1, false},
    {"angle_noise_deg", &Fidelity::angle_noise_deg, 0.0, kInf, false},
    {"torque_noise_nm", &Fidelity::torque_noise_nm, 0.0, kInf, false},
    {"accel_noise_m_s2", &Fidelity::accel_noise_m_s2, 0.0, kInf, false},
    {"emg_noise_mv", &Fidelity::emg_noise_mv, 0.0, kInf, false},
    {"emg_m_wave_mv", &Fidelity::emg_m_wave_mv, 0.0, kInf, false},
    {"cocontraction_per_min", &Fidelity::cocontraction_per_min, 0.0, kInf, false},
    {"cocontraction_torque_nm", &Fidelity::cocontraction_torque_nm, 0.0, kInf, false},
    {"cocontraction_emg_mv", &Fidelity::cocontraction_emg_mv, 0.0, kInf, false},
};
constexpr const char* kQuantiseKey = "quantise_adc";

const NumberField<Anthropometrics> kAnthroNumbers[] = {
    {"body_mass_kg", &Anthropometrics::body_mass_kg, 0.0, kInf, true},
    {"height_m", &Anthropometrics::height_m, 0.0, kInf, true},
    {"shank_length_m", &Anthropometrics::shank_length_m, 0.0, kInf, true},
    {"accel_distance_m", &Anthropometrics::accel_distance_m, 0.0, 1.0, true},
    {"thigh_elevation_deg", &Anthropometrics::thigh_elevation_deg, -45.0, 45.0, false},
};

std::string Num(double v) {
  std::string s = std::to_string(v);
  while (s.size() > 1 && s.back() == '0') s.pop_back();
  if (!s.empty() && s.back() == '.') s.pop_back();
  return s;
}

template <class T>
Status CheckNumber(const NumberField<T>& f, double v, const std::string& path) {
  if (!std::isfinite(v)) return Status::InvalidArgument("must be finite", path);
  const bool low = f.lo_open ? !(v > f.lo) : !(v >= f.lo);
  if (low || v > f.hi) {
    std::string range = std::string(f.lo_open ? "(" : "[") + Num(f.lo) + ", " +
                        (f.hi == kInf ? std::string("inf)") : Num(f.hi) + "]");
    return Status::InvalidArgument("must be in " + range + ", got " + Num(v), path);
  }
  return {};
}

template <class T, std::size_t N>
Status CheckAll(const NumberField<T> (&fields)[N], const T& value, const std::string& prefix) {
  for (const auto& f : fields) {
    Status st = CheckNumber(f, value.*(f.member), prefix + "." + f.key);
    if (!st.ok()) return st;
  }
  return {};
}

// Reads the optional section `key` of `j` into `out` (fields default).
template <class T, std::size_t N>
Status ReadSection(const json& j, const char* key, const NumberField<T> (&fields)[N],
                   const char* bool_key, bool T::*bool_member, T& out) {
  const auto it = j.find(key);
  if (it == j.end() || it->is_null()) return {};
  if (!it->is_object()) return Status::InvalidArgument("must be an object", key);
  for (auto m = it->begin(); m != it->end(); ++m) {
    const std::string path = std::string(key) + "." + m.key();
    if (bool_key != nullptr && m.key() == bool_key) {
      if (!m->is_boolean()) return Status::InvalidArgument("must be true or false", path);
      out.*bool_member = m->get<bool>();
      continue;
    }
    const NumberField<T>* field = nullptr;
    for (const auto& f : fields) {
      if (m.key() == f.key) field = &f;
    }
    if (field == nullptr) return Status::InvalidArgument("unknown field", path);
    if (!m->is_number()) return Status::InvalidArgument("must be a number", path);
    const double v = m->get<double>();
    Status st = CheckNumber(*field, v, path);
    if (!st.ok()) return st;
    out.*(field->member) = v;
  }
  return {};
}

Status CheckLevels(const VirtualSubject& s) {
  if (!std::isfinite(s.threshold_ma) || s.threshold_ma < 0.0) {
    return Status::InvalidArgument("must be a finite amplitude >= 0 mA", "threshold_ma");
  }
  if (!std::isfinite(s.max_tolerated_ma) || !(s.max_tolerated_ma > s.threshold_ma) ||
      s.max_tolerated_ma > 100.0) {
    return Status::InvalidArgument(
        "must be above threshold_ma (" + Num(s.threshold_ma) + " mA) and at most 100 mA",
        "max_tolerated_ma");
  }
  return {};
}

}  // namespace

Fidelity Fidelity::Off() {
  Fidelity f;
  f.twitch_variation = 0.0;
  f.series_stiffness_nm_per_deg = 0.0;
  f.hysteresis_nm = 0.0;
  f.static_friction_nm = 0.0;
  f.fatigue_rate_per_s = 0.0;
  f.potentiation_max = 0.0;
  f.potentiation_rate_per_s = 0.0;
  f.pot_nonlinearity = 0.0;
  f.angle_noise_deg = 0.0;
  f.torque_noise_nm = 0.0;
  f.accel_noise_m_s2 = 0.0;
  f.emg_noise_mv = 0.0;
  f.quantise_adc = false;
  f.emg_m_wave_mv = 0.0;
  f.cocontraction_per_min = 0.0;
  return f;
}

json FidelityToJson(const Fidelity& fidelity) {
  json j = json::object();
  for (const auto& f : kFidelityNumbers) j[f.key] = fidelity.*(f.member);
  j[kQuantiseKey] = fidelity.quantise_adc;
  return j;
}

json VirtualSubjectToJson(const VirtualSubject& s) {
  json anthro = json::object();
  for (const auto& f : kAnthroNumbers) anthro[f.key] = s.anthropometrics.*(f.member);
  return {{"name", s.name},
          {"seed", s.seed},
          {"truth", ParameterSetToJson(s.truth)},
          {"threshold_ma", s.threshold_ma},
          {"max_tolerated_ma", s.max_tolerated_ma},
          {"anthropometrics", anthro},
          {"fidelity", FidelityToJson(s.fidelity)}};
}

Status ValidateVirtualSubject(const VirtualSubject& s) {
  if (Status valid = CallModel(
          [&] {
            model::ValidateContraction(s.truth.contraction);
            (void)model::JointModel::FromParameters(s.truth);
          },
          "truth");
      !valid.ok()) {
    return valid;
  }
  if (s.truth.irc.empty()) return Status::InvalidArgument("must not be empty", "truth.irc");
  if (Status st = CheckLevels(s); !st.ok()) return st;
  if (Status st = CheckAll(kAnthroNumbers, s.anthropometrics, "anthropometrics"); !st.ok()) {
    return st;
  }
  return CheckAll(kFidelityNumbers, s.fidelity, "fidelity");
}

Result<VirtualSubject> VirtualSubjectFromJson(const json& j) {
  if (!j.is_object()) return Status::InvalidArgument("a virtual subject must be an object");
  static constexpr std::string_view kKnown[] = {
      "name", "seed", "truth", "threshold_ma", "max_tolerated_ma", "anthropometrics", "fidelity"};
  for (auto it = j.begin(); it != j.end(); ++it) {
    bool known = false;
    for (std::string_view k : kKnown) known = known || it.key() == k;
    if (!known) return Status::InvalidArgument("unknown field", it.key());
  }
  VirtualSubject s;
  if (const auto it = j.find("name"); it != j.end()) {
    if (!it->is_string()) return Status::InvalidArgument("must be a string", "name");
    s.name = it->get<std::string>();
  }
  if (const auto it = j.find("seed"); it != j.end()) {
    if (!it->is_number_unsigned()) {
      return Status::InvalidArgument("must be a non-negative integer", "seed");
    }
    s.seed = it->get<std::uint64_t>();
  }
  const auto truth = j.find("truth");
  if (truth == j.end()) return Status::InvalidArgument("missing required field", "truth");
  Result<model::ParameterSet> params = ParameterSetFromJson(*truth);
  if (!params.ok()) {
    const std::string& inner = params.status().field();
    return Status::InvalidArgument(params.status().message(),
                                   inner.empty() ? "truth" : "truth." + inner);
  }
  s.truth = std::move(params).value();
  for (const char* key : {"threshold_ma", "max_tolerated_ma"}) {
    const auto it = j.find(key);
    if (it == j.end()) return Status::InvalidArgument("missing required field", key);
    if (!it->is_number()) return Status::InvalidArgument("must be a number", key);
    (std::string_view(key) == "threshold_ma" ? s.threshold_ma : s.max_tolerated_ma) =
        it->get<double>();
  }
  if (Status st = CheckLevels(s); !st.ok()) return st;
  if (Status st = ReadSection<Anthropometrics>(j, "anthropometrics", kAnthroNumbers, nullptr,
                                               nullptr, s.anthropometrics);
      !st.ok()) {
    return st;
  }
  if (Status st = ReadSection<Fidelity>(j, "fidelity", kFidelityNumbers, kQuantiseKey,
                                        &Fidelity::quantise_adc, s.fidelity);
      !st.ok()) {
    return st;
  }
  if (Status st = ValidateVirtualSubject(s); !st.ok()) return st;
  return s;
}

}  // namespace fesbench::api
