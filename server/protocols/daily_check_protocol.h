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

/// The daily check's trials: the isometric ramp it compares and the free
/// swing it validates with (indices into the plan's trials).
struct DailyCheckSettings {
  int ramp_trial = 0;
  int swing_trial = 1;
  double lock_angle_deg = 90.0;
};

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

/// The daily check's evaluation, as its plan's RunAnalysis: EvaluateDailyCheck;
/// the report goes to RunResult::daily_check, a re-fit to its
/// parameter_set. A check that cannot be evaluated fails the run with the
/// reason.
class DailyCheckEvaluation final : public RunAnalysis {
 public:
  explicit DailyCheckEvaluation(DailyCheckSettings settings) : settings_(settings) {}

  const DailyCheckSettings& settings() const { return settings_; }
  api::Status Analyse(const std::vector<RecordedTrial>& trials, const SubjectContext& subject,
                      const model::JointLimits& stops, RunResult& result) const override;

 private:
  DailyCheckSettings settings_;
};

}  // namespace fesbench::server::protocols
