#pragma once

/// @file
/// What a run concluded (docs/PROTOCOLS.md, "Runs"; docs/API.md, Runs): one
/// typed outcome per run, written once with its terminal state and read
/// back as it was written. The run resource's `result`, `values`,
/// `tolerance` and `parameter_set_id` are views of it (RunResultJsonOf,
/// RunValuesOf), kept for the clients that read them.
///
/// The protocol's figures are typed by protocol family: the tolerance
/// test's, the amplitude search of the protocols that search one (rapid
/// parameterisation, active random binary), the daily check's report and
/// the tracking figures. Booleans are booleans.
///
/// The readers (…FromJson) ignore fields they do not know; a missing or
/// mistyped field they need is kInvalidArgument naming it.

#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/run_state.h"
#include "api/status.h"
#include "model/daily_check.h"

namespace fesbench::api {

/// The tolerance test's outcome (Appendix F part II.K).
struct ToleranceResult {
  std::optional<double> threshold_ma;  ///< first amplitude with torque above the band.
  double max_tolerated_ma = 0.0;       ///< amplitude when stopped (or the ceiling).
  double max_torque_nm = 0.0;          ///< largest smoothed torque (offset removed).
  double noise_band_nm = 0.0;          ///< torque band used for the threshold.
  bool stopped_by_clinician = false;
  std::vector<std::string> warnings;
};
/// {"threshold_ma" (null if none), "max_tolerated_ma", "max_torque_nm",
///  "noise_band_nm", "stopped_by_clinician", "warnings"}.
nlohmann::json ToleranceResultToJson(const ToleranceResult& result);
Result<ToleranceResult> ToleranceResultFromJson(const nlohmann::json& json);

/// The tolerance test's conclusion (docs/PROTOCOLS.md, `tolerance_test`;
/// docs/SAFETY.md, tolerance test ceiling).
struct ToleranceOutcome {
  /// What the detector measured (Appendix F part II.K); absent for runs
  /// stored before outcomes were (only the recorded limits are known).
  std::optional<ToleranceResult> test;
  /// The limits the run reports: the threshold and max tolerated it stored
  /// in the session, or measured without storing; no max when the ramp
  /// ended at its ceiling.
  std::optional<double> threshold_ma;
  std::optional<double> max_tolerated_ma;
  /// The ramp ended where the subject signalled the limit (not the
  /// clinician's stop, not the ceiling); unknown for older runs.
  std::optional<bool> subject_signalled_limit;
  /// The ramp reached its ceiling unsignalled: no max tolerated was
  /// measured, and `message` says what to do.
  bool ended_at_ceiling = false;
  std::string message;
};
/// {"test" (ToleranceResultToJson, or absent), "threshold_ma",
///  "max_tolerated_ma" (null if none), "subject_signalled_limit" (bool, or
///  absent), "ended_at_ceiling" (bool), "message"}.
nlohmann::json ToleranceOutcomeToJson(const ToleranceOutcome& outcome);
Result<ToleranceOutcome> ToleranceOutcomeFromJson(const nlohmann::json& json);

/// The amplitude a run searched for (§5.4.3) or chose from a torque target
/// (rapid_parameterisation, active_random_binary; docs/PROTOCOLS.md).
struct AmplitudeSearchOutcome {
  std::optional<double> rb_amplitude_ma;              ///< the random binary's top level.
  std::optional<double> full_extension_amplitude_ma;  ///< reaching full extension (§5.4.3).
  std::optional<bool> full_extension_reached;         ///< the knee got there.
};
/// {"rb_amplitude_ma", "full_extension_amplitude_ma", "full_extension_reached"}, each
/// present only when known.
nlohmann::json AmplitudeSearchOutcomeToJson(const AmplitudeSearchOutcome& outcome);
Result<AmplitudeSearchOutcome> AmplitudeSearchOutcomeFromJson(const nlohmann::json& json);

/// "no_change", "refit", "rapid_due" (model/daily_check.h).
std::optional<model::DailyVerdict> ParseDailyVerdict(std::string_view name);

/// One drift the daily check measured (model::Drift).
struct DailyDrift {
  std::string name;
  std::optional<double> stored, today, change, bound;  ///< null: not finite.
  bool moved = false;
};

/// The daily check's report (docs/PROTOCOLS.md, `daily_check`).
struct DailyCheckOutcome {
  model::DailyVerdict verdict = model::DailyVerdict::kNoChange;
  std::string summary;
  std::vector<DailyDrift> drifts;
  std::vector<std::string> refitted;        ///< what a re-fit changed.
  std::optional<double> recruitment_misfit;
  std::int64_t history_sets = 0;            ///< the leg's sets that set the bounds.
  std::string compared_with;                ///< "the set's own ramp trial" or "the set's model".
  std::optional<std::int64_t> base_parameter_set_id;  ///< the set compared against.
  std::optional<double> swing_e_rms_stored_deg, swing_e_rms_updated_deg;
};
/// The report as daily_check has always sent it: {"verdict", "summary",
/// "drifts": [{name, stored, today, change, bound, moved}], "refitted",
/// "recruitment_misfit", "history_sets", "compared_with",
/// "base_parameter_set_id", "swing_e_rms_deg": {"stored", "updated"}}.
nlohmann::json DailyCheckOutcomeToJson(const DailyCheckOutcome& outcome);
Result<DailyCheckOutcome> DailyCheckOutcomeFromJson(const nlohmann::json& json);

/// A tracking run's figures (docs/PROTOCOLS.md, `tracking`): errors,
/// saturation, charge and the controller's gains, by name with units.
struct TrackingOutcome {
  std::map<std::string, double> figures;
};

/// What a run concluded.
struct RunOutcome {
  RunState state = RunState::kFailed;  ///< done, failed or aborted.
  std::string reason;                  ///< why failed or aborted; empty when done.
  /// The set the run made and stored (rapid_parameterisation; daily_check's re-fit).
  std::optional<std::int64_t> parameter_set_id;
  /// The leg's set the run was gated by or compared against (tracking,
  /// daily_check, the prediction protocols).
  std::optional<std::int64_t> used_parameter_set_id;
  /// The session revision the run wrote (tolerance_test's limits).
  std::optional<int> session_revision;
  std::optional<ToleranceOutcome> tolerance;
  std::optional<AmplitudeSearchOutcome> amplitude_search;
  std::optional<DailyCheckOutcome> daily_check;
  std::optional<TrackingOutcome> tracking;
};
/// {"state", "reason", "parameter_set_id", "used_parameter_set_id",
///  "session_revision" (each null when none), and "tolerance",
///  "amplitude_search", "daily_check", "tracking" (figures by name) when
///  the run has them}.
nlohmann::json RunOutcomeToJson(const RunOutcome& outcome);
/// "state" is needed and must be final.
Result<RunOutcome> RunOutcomeFromJson(const nlohmann::json& json);

/// RunView's `result`: tolerance_test (done) {"threshold_ma",
/// "max_tolerated_ma", "session_revision" (null: not stored),
/// "subject_signalled_limit"?, "ended_at_ceiling"?, "message"?};
/// daily_check (done) its report with "parameter_set_id"; any other run
/// that stored a set {"parameter_set_id"}; else null.
nlohmann::json RunResultJsonOf(const RunOutcome& outcome);
/// RunView's `values`: the figures as numbers (a boolean as 1 or 0).
std::map<std::string, double> RunValuesOf(const RunOutcome& outcome);
}  // namespace fesbench::api
