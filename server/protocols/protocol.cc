#include "server/protocols/protocol.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <sstream>

#include "api/json_fields.h"
#include "api/trial.h"

namespace fesbench::server::protocols {
namespace {
std::string Unit(std::string_view name) {
  if (name.ends_with("_ma_per_s")) return "mA/s";
  const std::string unit = api::ChannelUnit(name);
  return unit.empty() ? "1" : unit;
}

std::string Format(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

}  // namespace

std::string_view ScalingName(Scaling scaling) {
  switch (scaling) {
    case Scaling::kNone:
      return "none";
    case Scaling::kThreshold:
      return "threshold";
    case Scaling::kMaxTolerated:
      return "max_tolerated";
    case Scaling::kStimRange:
      return "stim_range";
    case Scaling::kRangeMin:
      return "range_min";
    case Scaling::kRangeMax:
      return "range_max";
    case Scaling::kToleranceCeiling:
      return "tolerance_ceiling";
  }
  return "none";
}

std::string_view BenchModeName(BenchMode mode) {
  switch (mode) {
    case BenchMode::kLocked:
      return "locked";
    case BenchMode::kMotor:
      return "motor";
    case BenchMode::kDecoupled:
      return "decoupled";
    case BenchMode::kMixed:
      return "mixed";
  }
  return "mixed";
}

const ParameterSpec* ProtocolDescription::FindParameter(std::string_view name) const {
  for (const ParameterSpec& p : parameters) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

const ProtocolDescription* FindProtocol(std::string_view name) {
  for (const ProtocolDescription& p : ProtocolCatalog()) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

api::Status ValidateSubject(const SubjectContext& s) {
  const auto bad = [](std::string field, std::string message) {
    return api::Status::InvalidArgument(std::move(message), "subject." + field);
  };
  for (const auto& [field, v] :
       {std::pair{"threshold_ma", s.threshold_ma},
        std::pair{"max_tolerated_ma", s.max_tolerated_ma},
        std::pair{"min_angle_deg", s.min_angle_deg}, std::pair{"max_angle_deg", s.max_angle_deg}}) {
    if (!std::isfinite(v)) return bad(field, "must be finite");
  }
  if (s.threshold_ma < 0.0) return bad("threshold_ma", "must be >= 0 mA");
  if (!(s.max_tolerated_ma > s.threshold_ma) || s.max_tolerated_ma > 100.0) {
    return bad("max_tolerated_ma", "must be above the threshold and at most 100 mA");
  }
  if (s.min_angle_deg < 0.0) return bad("min_angle_deg", "must be >= 0 deg");
  if (!(s.max_angle_deg > s.min_angle_deg) || s.max_angle_deg > 180.0) {
    return bad("max_angle_deg", "must be above min_angle_deg and at most 180 deg");
  }
  if (s.inertia_kgm2 && !(std::isfinite(*s.inertia_kgm2) && *s.inertia_kgm2 > 0.0)) {
    return bad("inertia_kgm2", "must be finite and > 0");
  }
  return api::Status::Ok();
}

double DefaultFor(const ParameterSpec& spec, const SubjectContext& s) {
  switch (spec.scaling) {
    case Scaling::kNone:
      return spec.default_value;
    case Scaling::kThreshold:
      return s.threshold_ma;
    case Scaling::kMaxTolerated:
      return s.max_tolerated_ma;
    case Scaling::kStimRange: {
      // To 0.1 mA, the resolution a clinician reads and types (docs/PROTOCOLS.md),
      // never above the max tolerated.
      const double exact =
          s.threshold_ma + spec.default_value * (s.max_tolerated_ma - s.threshold_ma);
      return std::min(std::round(exact * 10.0) / 10.0, s.max_tolerated_ma);
    }
    case Scaling::kRangeMin:
      return s.min_angle_deg;
    case Scaling::kRangeMax:
      return s.max_angle_deg;
    case Scaling::kToleranceCeiling:
      return s.max_tolerated_recorded ? s.max_tolerated_ma : spec.default_value;
  }
  return spec.default_value;
}

std::string NoApprovedSetMessage(std::string_view what) {
  return std::string(what) +
         " needs the leg's approved parameter set: no set is approved for the leg; a clinician "
         "approves one of its sets (POST /api/v1/parameter-sets/{id}/approve with a note, or "
         "`fesbench params approve ID --note TEXT`), or runs rapid_parameterisation, whose set "
         "is approved by its run";
}

namespace {

// docs/SAFETY.md, "Stimulation limit": stimulation never above the session's max tolerated
// amplitude. The tolerance test measures that maximum, so on a session with
// a recorded one it may go above it only by a clinician's explicit, audited
// decision; its ramp starts below its ceiling.
api::Status CheckToleranceCeiling(const ParameterValues& v, const SubjectContext& subject) {
  const double ceiling = v.at("ceiling_ma");
  if (subject.ceiling_above_max) {
    // The reason is the clinician's decision in words (docs/SAFETY.md,
    // tolerance test ceiling): blank or control characters authorise nothing.
    if (api::Status text = api::CheckPrintableText(*subject.ceiling_above_max, "ceiling_reason");
        !text.ok()) {
      return text;
    }
    if (!subject.max_tolerated_recorded) {
      return api::Status::InvalidArgument(
          "the session has no recorded max tolerated amplitude: ceiling_ma needs no reason",
          "ceiling_reason");
    }
    if (!(ceiling > subject.max_tolerated_ma)) {
      return api::Status::InvalidArgument(
          "ceiling_ma " + Format(ceiling) + " mA is not above the session's max tolerated " +
              Format(subject.max_tolerated_ma) + " mA: no reason is needed",
          "ceiling_reason");
    }
  } else if (subject.max_tolerated_recorded && ceiling > subject.max_tolerated_ma) {
    return api::Status::InvalidArgument(
        "above the session's max tolerated amplitude " + Format(subject.max_tolerated_ma) +
            " mA: a ceiling above it needs an explicit ceiling_reason (audited)",
        "parameters.ceiling_ma");
  }
  if (!(v.at("start_ma") < ceiling)) {
    return api::Status::InvalidArgument(
        "at or above the ramp's ceiling " + Format(ceiling) + " mA", "parameters.start_ma");
  }
  return api::Status::Ok();
}

}  // namespace

api::Result<ParameterValues> ResolveParameters(const ProtocolDescription& protocol,
                                               const ParameterValues& values,
                                               const SubjectContext& subject) {
  if (api::Status st = ValidateSubject(subject); !st.ok()) return st;
  for (const auto& [name, v] : values) {
    if (protocol.FindParameter(name) == nullptr) {
      return api::Status::InvalidArgument("unknown parameter of protocol " + protocol.name,
                                          "parameters." + name);
    }
  }
  ParameterValues out;
  for (const ParameterSpec& p : protocol.parameters) {
    const auto it = values.find(p.name);
    const bool given = it != values.end();
    const double v = given ? it->second : DefaultFor(p, subject);
    const std::string field = "parameters." + p.name;
    if (!std::isfinite(v)) return api::Status::InvalidArgument("must be finite", field);
    if (p.integer && std::floor(v) != v) {
      return api::Status::InvalidArgument("must be a whole number", field);
    }
    if (p.is_rest && v < protocol.min_rest_s) {
      return api::Status::InvalidArgument("rest below minimum: " + Format(v) + " s < " +
                                              Format(protocol.min_rest_s) + " s of " +
                                              protocol.name,
                                          field);
    }
    if (v < p.min_value || v > p.max_value) {
      const std::string unit = Unit(p.name);
      const std::string u = unit == "1" ? "" : " " + unit;
      return api::Status::InvalidArgument("must be " + Format(p.min_value) + "–" +
                                              Format(p.max_value) + u + ", got " + Format(v) + u,
                                          field);
    }
    const bool stim = p.scaling == Scaling::kThreshold || p.scaling == Scaling::kMaxTolerated ||
                      p.scaling == Scaling::kStimRange;
    if (stim && v > subject.max_tolerated_ma) {
      return api::Status::InvalidArgument(
          "above the session's max tolerated amplitude " + Format(subject.max_tolerated_ma) + " mA",
          field);
    }
    // Every angle (lock, reference, trajectory limits) inside the range of motion.
    const bool angle = p.name.ends_with("_deg") && !p.name.ends_with("_per_deg");
    if (angle && (v < subject.min_angle_deg || v > subject.max_angle_deg)) {
      return api::Status::InvalidArgument("outside the subject's range of motion [" +
                                              Format(subject.min_angle_deg) + ", " +
                                              Format(subject.max_angle_deg) + "] deg",
                                          field);
    }
    out[p.name] = v;
  }
  if (protocol.measures_max_tolerated) {
    if (api::Status st = CheckToleranceCeiling(out, subject); !st.ok()) return st;
  } else if (subject.ceiling_above_max) {
    return api::Status::InvalidArgument("only a tolerance_test has a ceiling above the max",
                                        "ceiling_reason");
  }
  return out;
}

namespace {

// Labels in clinician words; `advanced` = folded away in the web form.
const std::map<std::string, ParameterPresentation, std::less<>>& PresentationTable() {
  static const std::map<std::string, ParameterPresentation, std::less<>> table = {
      // Stimulation levels (the subject's).
      {"threshold_ma", {"Stimulation threshold", "mA", false}},
      {"max_ma", {"Maximum stimulation (max tolerated)", "mA", false}},
      {"amplitude_ma", {"Random-binary amplitude", "mA", false}},
      {"level_fraction", {"Step level (fraction of threshold→max)", "1", false}},
      {"conditioning_fraction", {"Conditioning level (fraction of threshold→max)", "1", true}},
      {"below_threshold_ma", {"Start below threshold", "mA", true}},
      {"above_threshold_ma", {"Lowest level above threshold", "mA", true}},
      {"rb_torque_nm",
       {"Random-binary target torque (0 = the amplitude that reaches full extension)", "N·m",
        true}},
      {"rb_level_min_fraction",
       {"Lowest random-binary level (fraction of the amplitude)", "1", true}},
      {"rb_min_top_fraction",
       {"Least top random-binary level (fraction of threshold→max)", "1", true}},
      {"extension_target_fraction",
       {"Full extension for the search (fraction of the range inside its end)", "1", true}},
      {"release_margin_fraction",
       {"Release angles inside the range ends (fraction of the range)", "1", true}},
      // Tolerance test.
      {"start_ma", {"Starting amplitude", "mA", false}},
      {"rate_ma_per_s", {"Amplitude rise rate", "mA/s", false}},
      {"ceiling_ma", {"Highest amplitude if not stopped", "mA", false}},
      {"threshold_torque_nm", {"Torque counted as a response", "N·m", true}},
      {"min_torque_at_max_nm", {"Torque expected at max (warning below)", "N·m", true}},
      // Angles and motion.
      {"lock_angle_deg", {"Knee angle of the locked brace", "deg", true}},
      {"min_angle_deg", {"Lowest knee angle (full extension)", "deg", false}},
      {"max_angle_deg", {"Highest knee angle (flexion)", "deg", false}},
      {"reference_deg", {"Reference angle for the torque offset", "deg", true}},
      {"max_speed_deg_s", {"Fastest motor speed", "deg/s", true}},
      {"max_velocity_deg_s", {"Motor velocity limit", "deg/s", true}},
      // Timing.
      {"duration_s", {"Length of each stimulation train", "s", false}},
      {"settle_s", {"Settling time before recording", "s", true}},
      {"swing_settle_s", {"Free swing before recording", "s", true}},
      {"release_move_s", {"Motor move to each release angle", "s", true}},
      {"release_hold_s", {"Hold before each release", "s", true}},
      {"release_swing_s", {"Free swing recorded after each release", "s", true}},
      {"search_s", {"Full-extension search length", "s", true}},
      {"fall_s", {"Free swing recorded after the search", "s", true}},
      {"rest_s", {"Rest between elements", "s", true}},
      {"interval_s", {"Time between pulses", "s", true}},
      {"pause_s", {"Pause before each motor move", "s", true}},
      {"conditioning_s", {"Conditioning burst length", "s", true}},
      {"ramp_duration_s", {"Ramp length (up and down)", "s", true}},
      {"ramp_s", {"Ramp time", "s", true}},
      {"burst_s", {"Burst length", "s", true}},
      {"hold_s", {"Hold time", "s", true}},
      {"move_s", {"Move time between angles", "s", true}},
      {"lead_s", {"Quiet time before the first ramp", "s", true}},
      {"tail_s", {"Quiet time at the end", "s", true}},
      {"onset_s", {"Quiet time before the step", "s", true}},
      {"on_s", {"Step length", "s", false}},
      {"off_s", {"Quiet time after the step", "s", true}},
      {"up_s", {"Ramp-up time", "s", false}},
      {"down_s", {"Ramp-down time", "s", false}},
      // Counts and seeds.
      {"impulses", {"Number of single pulses at max", "1", true}},
      {"ramps", {"Number of ramps", "1", true}},
      {"levels", {"Number of levels", "1", true}},
      {"count", {"Number of pulses", "1", true}},
      {"positions", {"Number of angles per pass", "1", true}},
      {"speeds", {"Number of motor speeds", "1", true}},
      {"trajectories", {"Number of trajectories", "1", true}},
      {"dense", {"Dense train (1) or sparse train (0)", "1", true}},
      {"seed", {"Random pattern number", "1", true}},
      {"rb1_seed", {"First pattern number", "1", true}},
      {"rb2_seed", {"Second pattern number", "1", true}},
      {"active_seed", {"Active-swing pattern number", "1", true}},
      // Tracking.
      {"controller", {"Controller", "1", false}},
      {"target", {"Target", "1", false}},
      {"lo_deg", {"Lower target angle (extension side)", "deg", false}},
      {"hi_deg", {"Upper target angle (flexion side)", "deg", false}},
      {"frequency_hz", {"Sine frequency", "Hz", false}},
      {"hold_s", {"Time at each hold", "s", false}},
      {"move_s", {"Time between holds", "s", true}},
      {"lead_in_s", {"Lead-in to the target's start", "s", true}},
      {"kp_ma_per_deg", {"PID proportional gain (0 = tuned from the set)", "mA/deg", true}},
      {"ki_ma_per_deg_s", {"PID integral gain", "mA/(deg·s)", true}},
      {"kd_ma_s_per_deg", {"PID derivative gain", "mA·s/deg", true}},
      {"kp_nm_per_deg", {"Torque PID proportional gain (0 = tuned from the set)", "N·m/deg", true}},
      {"ki_nm_per_deg_s", {"Torque PID integral gain", "N·m/(deg·s)", true}},
      {"kd_nm_s_per_deg", {"Torque PID derivative gain", "N·m·s/deg", true}},
      {"max_rate_ma_per_s", {"Fastest amplitude change", "mA/s", true}},
      {"max_saturation_s", {"Longest saturation before the run stops", "s", true}},
      {"forgetting", {"Adaptive forgetting factor", "1", true}},
      {"parameter_set_id", {"Parameter set (0 = the leg's approved set)", "1", true}},
      {"swing_s", {"Validation free swing", "s", true}},
      // The pendulum test.
      {"release_angle_deg", {"Angle the shank is let go at", "deg", false}},
      {"release_count", {"Number of releases", "1", false}},
      // Anthropometrics.
      {"inertia_kgm2",
       {"Leg inertia (0 = the last parameter set's, else from weight and shank length)", "kg·m²",
        false}},
  };
  return table;
}

std::string DefaultRule(const ParameterSpec& p) {
  switch (p.scaling) {
    case Scaling::kNone:
      return "";
    case Scaling::kThreshold:
      return "the session's threshold";
    case Scaling::kMaxTolerated:
      return "the session's max tolerated amplitude";
    case Scaling::kStimRange:
      return Format(p.default_value * 100.0) + " % of threshold→max";
    case Scaling::kRangeMin:
      return "the lower end of the range of motion";
    case Scaling::kRangeMax:
      return "the upper end of the range of motion";
    case Scaling::kToleranceCeiling:
      return "the session's max tolerated amplitude; " + Format(p.default_value) +
             " mA when none is recorded";
  }
  return "";
}

bool IsStimulationScaling(Scaling s) {
  return s == Scaling::kThreshold || s == Scaling::kMaxTolerated || s == Scaling::kStimRange;
}

}  // namespace

ParameterPresentation PresentationOf(std::string_view name) {
  const auto& table = PresentationTable();
  if (const auto it = table.find(name); it != table.end()) return it->second;
  return {std::string(name), Unit(name), true};
}

ParameterPresentation PresentationOf(const ParameterSpec& spec) {
  ParameterPresentation look = PresentationOf(spec.name);
  if (!spec.label.empty()) look.label = spec.label;
  return look;
}

std::string ThesisSection(const ProtocolDescription& protocol) {
  const std::string& d = protocol.description;
  const std::size_t at = d.rfind("§");
  if (at == std::string::npos) return "";
  std::size_t end = at + std::string("§").size();
  while (end < d.size() && (std::isdigit(static_cast<unsigned char>(d[end])) || d[end] == '.')) {
    ++end;
  }
  while (end > at && d[end - 1] == '.') --end;  // a sentence's full stop
  return d.substr(at, end - at);
}

bool Stimulates(const ProtocolDescription& protocol) {
  return protocol.kind != ProtocolKind::kPassive;
}

api::ProtocolInfo ProtocolInfoOf(const ProtocolDescription& protocol,
                                  const SubjectContext* session, bool session_has_limits) {
  api::ProtocolInfo info{.name = protocol.name,
                         .version = protocol.version,
                         .title = protocol.title,
                         .description = protocol.description,
                         .thesis_section = ThesisSection(protocol),
                         .stimulates = Stimulates(protocol),
                         .bench_mode = std::string(BenchModeName(protocol.bench_mode)),
                         .min_rest_s = protocol.min_rest_s,
                         .measures_max_tolerated = protocol.measures_max_tolerated,
                         .follows_target = protocol.follows_target,
                         .offered_first = protocol.offered_first};
  for (const ParameterSpec& p : protocol.parameters) {
    const ParameterPresentation look = PresentationOf(p);
    api::ProtocolParameterInfo& out = info.parameters.emplace_back(api::ProtocolParameterInfo{
        .name = p.name,
        .label = look.label,
        .unit = look.unit,
        .description = p.description,
        .default_value = p.default_value,
        .default_rule = std::nullopt,
        .min = p.min_value,
        .max = p.max_value,
        .integer = p.integer,
        .advanced = look.advanced,
        .scales_to = std::string(ScalingName(p.scaling)),
        .rest = p.is_rest,
        .choices = p.choices});
    if (p.scaling != Scaling::kNone) {
      const bool resolvable =
          session != nullptr && (session_has_limits || !IsStimulationScaling(p.scaling));
      out.default_value = resolvable ? std::optional<double>(DefaultFor(p, *session)) : std::nullopt;
      out.default_rule = DefaultRule(p);
    }
  }
  return info;
}

nlohmann::json ProtocolToJson(const ProtocolDescription& protocol, const SubjectContext* session,
                              bool session_has_limits) {
  return api::ProtocolInfoToJson(ProtocolInfoOf(protocol, session, session_has_limits));
}

nlohmann::json CatalogToJson(const SubjectContext* session, bool session_has_limits) {
  std::vector<api::ProtocolInfo> protocols;
  for (const ProtocolDescription& p : ProtocolCatalog()) {
    protocols.push_back(ProtocolInfoOf(p, session, session_has_limits));
  }
  return api::ProtocolCatalogueToJson(protocols);
}

api::Result<api::StartRunRequest> ResolveChoiceNames(api::StartRunRequest request) {
  const ProtocolDescription* description = FindProtocol(request.protocol);
  if (description == nullptr) {
    return api::Status(api::ErrorCode::kNotFound, "protocol " + request.protocol + " not found",
                       "protocol");
  }
  for (const auto& [name, chosen] : request.choices) {
    const std::string field = "parameters." + name;
    const auto spec = std::find_if(description->parameters.begin(), description->parameters.end(),
                                   [&](const ParameterSpec& s) { return s.name == name; });
    if (spec == description->parameters.end() || spec->choices.empty()) {
      return api::Status::InvalidArgument("must be a number, got string", field);
    }
    const auto it = std::find(spec->choices.begin(), spec->choices.end(), chosen);
    if (it == spec->choices.end()) {
      std::string names;
      for (const std::string& c : spec->choices) names += (names.empty() ? "" : ", ") + c;
      return api::Status::InvalidArgument("'" + chosen.substr(0, 40) + "' is not one of " + names,
                                          field);
    }
    request.parameters[name] = static_cast<double>(it - spec->choices.begin());
  }
  request.choices.clear();
  return request;
}

}  // namespace fesbench::server::protocols
