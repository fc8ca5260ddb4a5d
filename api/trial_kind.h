#pragma once

/// @file
/// The kinds of trial the server knows (docs/MODEL.md, "Identification methods"): each protocol
/// names the kinds it records (server/protocols/protocol_registry.h), identification and prediction select trials
/// by these names, and an imported recording declares one. A kind is either
/// an exact name ("free_swing_passive") or a family whose members carry a
/// suffix ("passive_simultaneous_3", "active_random_binary_rb1",
/// "prediction_random_binary_s4").

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/status.h"

namespace fesbench::api {

/// Every kind of trial, one per row of TrialKinds().
enum class TrialKind {
  kToleranceTest,
  kRampIrc,
  kStepIrc,
  kImpulseIrc,
  kIsometricPrediction,
  kPassivePositions,
  kPassiveVelocities,
  kPassiveSimultaneous,
  kFreeSwingPassive,
  kActive,
  kPredictionRandomBinary,
  kPredictionStep,
  kPredictionRamp,
  kPredictionSine,
  kRapidRamp,
  kRapidHoldFlexion,
  kRapidPassive,
  kRapidHoldExtension,
  kRapidRelease,
  kRapidSearch,
  kRapidActive,
  kDailyCheckRamp,
  kDailyCheckSwing,
  kTracking,
  kPendulum,
};

struct TrialKindInfo {
  TrialKind kind;
  std::string_view name;         ///< the exact name, or the family's stem.
  bool family = false;           ///< members are "<name>_<suffix>" (and "<name>" itself).
  std::string_view description;  ///< what the trial holds, for people.
  /// Main-group channels a trial of this kind must have for identification
  /// or prediction to use it (t_s is always required).
  std::vector<std::string_view> required_channels;
  /// The motor moves or holds the knee: the angle is not a response to the
  /// stimulation, so such a trial is not predicted.
  bool motor = false;
  /// The knee is locked throughout: the trial is predicted isometrically
  /// (torque), not in free swing.
  bool knee_locked = false;
};

/// Every known kind, in protocol order.
const std::vector<TrialKindInfo>& TrialKinds();

/// The kind a trial name belongs to (exact match first, then the longest
/// family stem followed by "_" and a suffix of [a-z0-9_]), or nullptr.
const TrialKindInfo* FindTrialKind(std::string_view trial_name);

/// The kind of a trial name (FindTrialKind), or nullopt.
std::optional<TrialKind> TrialKindOf(std::string_view trial_name);

/// The kind's name (its row's `name`: "free_swing_passive", "active", ...).
std::string_view TrialKindName(TrialKind kind);
/// The kind named `name` exactly (a kind's name, not a member's), or nullopt.
std::optional<TrialKind> ParseTrialKind(std::string_view name);
/// The row of `kind`.
const TrialKindInfo& InfoOf(TrialKind kind);
/// A trial of this kind swings freely under stimulation: its knee angle is
/// the response a prediction is judged on (neither the motor nor a lock
/// holds the knee, and it is not the tolerance test).
bool IsFreeSwing(TrialKind kind);

/// A trial of this kind is recorded to validate a model (the §5.4.5
/// prediction protocols, isometric or free swing): identification never fits
/// on it.
bool IsValidation(TrialKind kind);

/// Checks that a trial name is a known kind (kInvalidArgument naming
/// `field` and listing the kinds otherwise).
Status ValidateTrialKindName(std::string_view trial_name, std::string_view field);

}  // namespace fesbench::api
