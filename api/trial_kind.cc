#include "api/trial_kind.h"

#include <algorithm>
#include <stdexcept>

namespace fesbench::api {

const std::vector<TrialKindInfo>& TrialKinds() {
  // The protocol that records each kind names it (server/protocols/protocol_registry.h).
  // Channels as identification reads them (services/identification_service.cc,
  // model/identify_*.h) and prediction (a stimulation input and the measured
  // angle it is compared with).
  static const std::vector<TrialKindInfo> kKinds = {
      {TrialKind::kToleranceTest,
       "tolerance_test",
       false,
       "ascending stimulation until the subject's maximum tolerated amplitude (§5.4.3)",
       {"stim_ma"}},
      {TrialKind::kRampIrc,
       "isometric_ramp_irc",
       false,
       "locked knee, slow stimulation ramp: recruitment curve by ramp correlation (§4.1.2)",
       {"stim_ma", "torque_nm"},
       false,
       true},
      {TrialKind::kStepIrc,
       "isometric_step_irc",
       false,
       "locked knee, stimulation steps: recruitment curve from step plateaus (§4.1.1)",
       {"stim_ma", "torque_nm"},
       false,
       true},
      {TrialKind::kImpulseIrc,
       "isometric_impulse_irc",
       false,
       "locked knee, single pulses: twitch and recruitment from impulse responses (§4.1.3)",
       {"stim_ma", "torque_nm"},
       false,
       true},
      {TrialKind::kIsometricPrediction,
       "isometric_prediction",
       false,
       "locked knee, the plateau profile of Fig. 5-8: isometric torque prediction (§5.3.4)",
       {"stim_ma", "torque_nm"},
       false,
       true},
      {TrialKind::kPassivePositions,
       "passive_positions",
       false,
       "motor holds the relaxed knee at angles: passive torque-angle (§4.2.1)",
       {"angle_deg", "torque_nm"},
       true},
      {TrialKind::kPassiveVelocities,
       "passive_velocities",
       false,
       "motor moves the relaxed knee at constant speeds: passive torque-velocity (§4.2.1)",
       {"angle_deg", "torque_nm"},
       true},
      {TrialKind::kPassiveSimultaneous,
       "passive_simultaneous",
       true,
       "motor moves the relaxed knee along a trajectory: both passive curves at once (§4.2.2)",
       {"angle_deg", "torque_nm"},
       true},
      {TrialKind::kFreeSwingPassive,
       "free_swing_passive",
       false,
       "decoupled relaxed knee released from flexion: passive curves and inertia (§4.2.3)",
       {"angle_deg"}},
      {TrialKind::kPendulum,
       "pendulum",
       true,
       "relaxed knee held in extension and let go, no stimulation (the pendulum test): the "
       "passive curves, with J given (MODEL.md, passive-only identification)",
       {"angle_deg"}},
      {TrialKind::kActive,
       "active_random_binary",
       true,
       "decoupled knee under random binary stimulation: active curves (§4.3)",
       {"stim_ma", "angle_deg"}},
      {TrialKind::kPredictionRandomBinary,
       "prediction_random_binary",
       true,
       "decoupled knee under random binary stimulation, for validation (§6.9)",
       {"stim_ma", "angle_deg"}},
      {TrialKind::kPredictionStep,
       "prediction_step",
       false,
       "decoupled knee under a stimulation step, for validation",
       {"stim_ma", "angle_deg"}},
      {TrialKind::kPredictionRamp,
       "prediction_ramp",
       false,
       "decoupled knee under a stimulation ramp, for validation",
       {"stim_ma", "angle_deg"}},
      {TrialKind::kPredictionSine,
       "prediction_sine",
       false,
       "decoupled knee under sinusoidal stimulation, for validation",
       {"stim_ma", "angle_deg"}},
      {TrialKind::kRapidRamp,
       "rapid_isometric_ramp_irc",
       false,
       "rapid routine: locked-knee ramp for the recruitment curve (§7.4.1)",
       {"stim_ma", "torque_nm"},
       false,
       true},
      {TrialKind::kRapidHoldFlexion,
       "rapid_release_hold_flexion",
       false,
       "rapid routine: the motor's hold in flexion before the release (inertia from it)",
       {"angle_deg", "torque_nm"},
       true},
      {TrialKind::kRapidPassive,
       "rapid_free_swing_passive",
       false,
       "rapid routine: release from flexion (passive curves)",
       {"angle_deg"}},
      {TrialKind::kRapidHoldExtension,
       "rapid_release_hold_extension",
       false,
       "rapid routine: the motor's hold in extension before the release (inertia from it)",
       {"angle_deg", "torque_nm"},
       true},
      {TrialKind::kRapidRelease,
       "rapid_release_extension",
       false,
       "rapid routine: release from extension (passive curves)",
       {"angle_deg"}},
      {TrialKind::kRapidSearch,
       "rapid_extension_search",
       false,
       "rapid routine: ascending search for the amplitude of full extension (§5.4.3)",
       {"stim_ma", "angle_deg"}},
      {TrialKind::kRapidActive,
       "rapid_active_random_binary",
       false,
       "rapid routine: random binary stimulation (active curves)",
       {"stim_ma", "angle_deg"}},
      {TrialKind::kDailyCheckRamp,
       "daily_check_ramp_irc",
       false,
       "daily check: impulses and one cosine ramp, knee locked (pole, IRC, full-scale torque)",
       {"stim_ma", "torque_nm"},
       false,
       true},
      {TrialKind::kDailyCheckSwing,
       "daily_check_swing",
       false,
       "daily check: random-binary free swing that validates the outcome",
       {"stim_ma", "angle_deg"}},
      {TrialKind::kTracking,
       "tracking",
       true,
       "closed-loop tracking of a target knee angle (tracking_sine, tracking_holds, "
       "tracking_ramp): target_deg and the controller's feedforward_ma, correction_ma, "
       "tau_scale_nm beside the usual channels (§7.6.3)",
       {"stim_ma", "angle_deg", "target_deg"}},
  };
  return kKinds;
}

namespace {

bool IsSuffix(std::string_view s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
  });
}

}  // namespace

const TrialKindInfo* FindTrialKind(std::string_view trial_name) {
  const TrialKindInfo* best = nullptr;
  for (const TrialKindInfo& k : TrialKinds()) {
    if (trial_name == k.name) return &k;
    if (k.family && trial_name.size() > k.name.size() + 1 && trial_name.starts_with(k.name) &&
        trial_name[k.name.size()] == '_' && IsSuffix(trial_name.substr(k.name.size() + 1)) &&
        (best == nullptr || k.name.size() > best->name.size())) {
      best = &k;
    }
  }
  return best;
}

std::optional<TrialKind> TrialKindOf(std::string_view trial_name) {
  const TrialKindInfo* info = FindTrialKind(trial_name);
  if (info == nullptr) return std::nullopt;
  return info->kind;
}

const TrialKindInfo& InfoOf(TrialKind kind) {
  for (const TrialKindInfo& k : TrialKinds()) {
    if (k.kind == kind) return k;
  }
  throw std::logic_error("TrialKind without a row in TrialKinds()");
}

std::string_view TrialKindName(TrialKind kind) { return InfoOf(kind).name; }

std::optional<TrialKind> ParseTrialKind(std::string_view name) {
  for (const TrialKindInfo& k : TrialKinds()) {
    if (k.name == name) return k.kind;
  }
  return std::nullopt;
}

bool IsFreeSwing(TrialKind kind) {
  const TrialKindInfo& info = InfoOf(kind);
  return !info.motor && !info.knee_locked && kind != TrialKind::kToleranceTest;
}

bool IsValidation(TrialKind kind) {
  switch (kind) {
    case TrialKind::kIsometricPrediction:
    case TrialKind::kPredictionRandomBinary:
    case TrialKind::kPredictionStep:
    case TrialKind::kPredictionRamp:
    case TrialKind::kPredictionSine:
      return true;
    default:
      return false;
  }
}

Status ValidateTrialKindName(std::string_view trial_name, std::string_view field) {
  if (FindTrialKind(trial_name) != nullptr) return Status::Ok();
  std::string known;
  for (const TrialKindInfo& k : TrialKinds()) {
    if (!known.empty()) known += ", ";
    known += k.name;
    if (k.family) known += "[_suffix]";
  }
  return Status::InvalidArgument(
      "unknown trial kind '" + std::string(trial_name) + "'; known kinds: " + known,
      std::string(field));
}

}  // namespace fesbench::api
