#pragma once

/// @file
/// What a tolerance_test run produced, as clients read it from the run
/// resource's and the end event's `result` (docs/API.md, Runs;
/// docs/PROTOCOLS.md, `tolerance_test`): the measured limits and the session
/// revision that stores them. The reader ignores fields it does not know.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "api/status.h"

namespace fesbench::api {

struct ToleranceRunResult {
  std::optional<double> threshold_ma;      ///< null when no threshold was found.
  std::optional<double> max_tolerated_ma;  ///< null when none was recorded.
  /// The session revision that stores the limits; unset when the run
  /// measured them but did not store them.
  std::optional<int> session_revision;
  std::optional<bool> subject_signalled_limit;  ///< when the run's values say.
  bool ended_at_ceiling = false;                ///< stopped at the ceiling: no maximum recorded.
  std::string message;                          ///< why, when ended_at_ceiling.
  friend bool operator==(const ToleranceRunResult&, const ToleranceRunResult&) = default;
};

/// {"threshold_ma", "max_tolerated_ma", "session_revision" (null when not
///  stored)} plus "subject_signalled_limit" when known and
///  "ended_at_ceiling": true, "message" when the run ended at its ceiling.
nlohmann::json ToleranceRunResultToJson(const ToleranceRunResult& outcome);
/// nullopt when `result` is not a tolerance outcome (not an object with a
/// "session_revision" field: another protocol's result, or null);
/// kInvalidArgument naming a mistyped field.
Result<std::optional<ToleranceRunResult>> ToleranceRunResultFromJson(const nlohmann::json& result);

}  // namespace fesbench::api
