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

#include "api/analysis_results.h"
#include "api/status.h"
#include "server/services/actor.h"
#include "server/services/prediction_service.h"
#include "storage/database.h"

namespace fesbench::server::services {

/// The result's wire form (api/analysis_results.h).
using ModelVerdict = api::ModelVerdict;
using api::ModelVerdictName;
using ModelCheckThresholds = api::ModelCheckThresholds;
using ModelCheckTrial = api::ModelCheckTrial;
using ModelCheck = api::ModelCheck;

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
