#pragma once

/// @file
/// What a daily_check run concludes (docs/PROTOCOLS.md; model/daily_check.h): today's
/// ramp trial against the leg's stored set, and the validation swing
/// predicted by the stored set and by the re-fitted one.

#include <nlohmann/json.hpp>
#include <optional>
#include <vector>

#include "model/parameter_set.h"
#include "model/simulate.h"
#include "server/protocols/plan.h"
#include "server/protocols/protocol.h"

namespace fesbench::server::protocols {

struct RecordedTrial;

struct DailyCheckOutcome {
  /// {"verdict", "summary", "drifts": [{name, stored, today, change, bound,
  /// moved}], "refitted": [...], "swing_e_rms_deg": {"stored", "updated"},
  /// "base_parameter_set_id"}.
  nlohmann::json report;
  std::optional<model::ParameterSet> updated;  ///< a re-fit to store.
};

/// Evaluates a finished daily check. kFailedPrecondition when the leg has
/// no set or today's ramp trial cannot be identified (the message says
/// why). A re-fit whose validation swing is predicted worse than the stored
/// set's by more than 1° is turned into "rapid_due".
api::Result<DailyCheckOutcome> EvaluateDailyCheck(const DailyCheckSettings& settings,
                                                  const std::vector<RecordedTrial>& trials,
                                                  const SubjectContext& subject,
                                                  const model::JointLimits& stops);

}  // namespace fesbench::server::protocols
