#pragma once

/// @file
/// The model check (docs/MODEL.md, "The model check"): whether a parameter
/// set is fit to drive stimulation of its leg, judged on the leg's stored
/// validation trials the set was not fitted on (the §5.4.5 prediction
/// protocols). Each trial is predicted and stored as a prediction
/// (PredictionService::Predict); its error is judged in the trial's own
/// quantity — the knee angle (deg) of a free swing, the torque (N·m) of an
/// isometric trial relative to the torque the trial reached — against the
/// thresholds of ModelCheckThresholds, and the set's verdict is its worst
/// trial's. The fit warnings are restated in a clinician's words.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "api/status.h"
#include "server/services/actor.h"
#include "server/services/prediction_service.h"
#include "storage/database.h"

namespace fesbench::server::services {

/// From best to worst; a set's verdict is its worst trial's.
enum class ModelVerdict {
  kGoodForControl,  ///< within the good thresholds on every fresh trial.
  kUseWithCare,     ///< within the care thresholds, or extrapolating much.
  kDoNotUse,        ///< a fresh trial beyond the care thresholds, or not predictable.
  kNoFreshTrials,   ///< nothing to judge on: record a prediction protocol first.
};

/// "good_for_control", "use_with_care", "do_not_use", "no_fresh_trials".
std::string_view ModelVerdictName(ModelVerdict verdict);

/// The thresholds of docs/MODEL.md, "The model check".
struct ModelCheckThresholds {
  double angle_good_deg = 3.0;  ///< free swing: E_RMS at most this is good.
  double angle_care_deg = 6.0;  ///< at most this: use with care; beyond: do not use.
  /// Isometric: E_RMS as a share of the torque range the trial measured.
  double torque_good_share = 0.15;
  double torque_care_share = 0.30;
  /// A free-swing prediction with more than this share of its samples
  /// outside the identified ranges is at best "use with care".
  double outside_care_share = 0.20;
};

/// One fresh trial, predicted.
struct ModelCheckTrial {
  std::int64_t trial_id = 0;
  std::string trial_name;
  std::int64_t session_id = 0;
  std::optional<std::int64_t> prediction_id;  ///< unset if the prediction failed.
  std::string quantity;                       ///< "knee angle" or "torque".
  std::string unit;                           ///< "deg" or "N.m".
  std::optional<double> e_rms;                ///< in `unit`.
  /// Isometric: the torque range the trial measured (N·m), E_RMS's reference.
  std::optional<double> measured_range;
  std::optional<double> share_outside;  ///< free swing: 0–1.
  ModelVerdict verdict = ModelVerdict::kDoNotUse;
  std::string explanation;  ///< the verdict's reason, in words with numbers and units.
};

struct ModelCheck {
  std::int64_t parameter_set_id = 0;
  ModelVerdict verdict = ModelVerdict::kNoFreshTrials;
  std::string summary;  ///< one sentence for the clinician.
  ModelCheckThresholds thresholds;
  std::vector<ModelCheckTrial> trials;
  /// The set's fit warnings restated for a clinician (ClinicalWarning), and
  /// the originals beside them.
  std::vector<std::string> warnings;
  std::vector<std::string> technical_warnings;
};

/// At most this many fresh trials are predicted (the newest).
inline constexpr std::size_t kModelCheckMaxTrials = 8;

/// Predicts the set on its leg's fresh validation trials (newest first, at
/// most kModelCheckMaxTrials) and judges them. kNotFound for an unknown set;
/// kPermissionDenied as PredictionService::Predict.
api::Result<ModelCheck> CheckModel(storage::Database& db, PredictionService& predictions,
                                   const Actor& actor, std::int64_t parameter_set_id,
                                   const ModelCheckThresholds& thresholds = {});

/// A fit warning of model/ (identification's report) in a clinician's words;
/// a warning of no known form is returned as it is.
std::string ClinicalWarning(const std::string& warning);

}  // namespace fesbench::server::services
