#pragma once

/// @file
/// The analysis jobs' results as they travel (docs/API.md, "Jobs": the
/// `result` of an identification, prediction, comparison or model-check
/// job): one definition for the server that writes them (server/services)
/// and the clients that read them (CLI, study). Keys carry units; an unset
/// optional travels as null.
///
/// The readers (…FromJson) check the types of the fields they know and
/// ignore fields they do not, so a client keeps working against a newer
/// server; a missing or mistyped field they need is kInvalidArgument naming
/// it. Names are read into enums (the prediction mode, the verdicts). A
/// figure that is not finite travels as null and reads back as NaN.

#include <cstddef>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/analysis_requests.h"
#include "api/status.h"
#include "model/evaluation.h"
#include "model/identify_common.h"
#include "model/simulate.h"

namespace fesbench::api {

/// One parameter-set version an identification stored.
struct StoredFit {
  std::int64_t parameter_set_id = 0;
  int version = 0;
  std::string model;  ///< the variant (model::ModelKindName).
  friend bool operator==(const StoredFit&, const StoredFit&) = default;
};

/// An identification job's result.
struct IdentificationResult {
  std::int64_t subject_id = 0;
  std::int64_t leg_id = 0;
  std::vector<StoredFit> stored;        ///< in request.models order.
  std::vector<std::int64_t> trial_ids;  ///< the trials used, ascending.
  model::IdentifyReport report;         ///< fit RMS, figures, warnings of all fits.
  std::int64_t audit_id = 0;
};
/// Field by field (model::IdentifyReport has no comparison of its own).
bool operator==(const IdentificationResult& a, const IdentificationResult& b);
/// {"fit_rms", "values", "warnings"}: a fit's report (the figures by name).
nlohmann::json IdentifyReportToJson(const model::IdentifyReport& report);
/// {"subject_id", "leg_id", "parameter_sets": [{"id", "version", "model"}],
///  "trial_ids", "report": {"fit_rms", "values", "warnings"}, "audit_id"}.
nlohmann::json IdentificationResultToJson(const IdentificationResult& result);
/// Needs "parameter_sets" (each with its "id").
Result<IdentificationResult> IdentificationResultFromJson(const nlohmann::json& json);

/// The errors of a prediction against a measured trial (thesis ch. 6).
struct PredictionErrors {
  std::string channel;  ///< "angle_deg" (free swing) or "torque_nm" (isometric).
  std::string unit;     ///< "deg" or "N.m".
  std::size_t samples = 0;
  double e_rms = 0.0;    ///< Eq. 6.9, unit.
  double e_abs = 0.0;    ///< Eq. 6.10, unit.
  double max_abs = 0.0;  ///< unit.
  /// Eq. 6.1 (dimensionless), over the samples where the measured value is
  /// not near zero; unset where no sample qualifies.
  std::optional<double> normalised_rms;
  std::size_t normalised_samples_used = 0;
  std::optional<double> e_ave;  ///< Eq. 6.2; unset where Σ data = 0.
  friend bool operator==(const PredictionErrors&, const PredictionErrors&) = default;
};
/// {"channel", "unit", "samples", "e_rms", "e_abs", "max_abs",
///  "normalised_rms" (null if undefined), "normalised_samples_used", "e_ave"}.
nlohmann::json PredictionErrorsToJson(const PredictionErrors& errors);
Result<PredictionErrors> PredictionErrorsFromJson(const nlohmann::json& json);

/// The predicted trajectory, one value per sample.
struct PredictionColumns {
  std::vector<double> t_s, stim_ma, angle_deg, velocity_deg_s, torque_nm, activation;
  friend bool operator==(const PredictionColumns&, const PredictionColumns&) = default;
};

/// A prediction job's result as it travels (the service's result holds the
/// whole simulation; this is what is sent of it).
struct PredictionView {
  std::optional<std::int64_t> prediction_id;  ///< unset until stored.
  std::optional<std::int64_t> evaluation_id;  ///< with a trial, once stored.
  std::int64_t parameter_set_id = 0;
  std::optional<std::int64_t> trial_id;
  PredictionMode mode = PredictionMode::kFreeSwing;
  std::string model;  ///< the variant simulated.
  double initial_angle_deg = 0.0;
  double initial_velocity_deg_s = 0.0;
  std::size_t samples = 0;
  std::optional<double> sample_rate_hz;      ///< with at least 2 samples.
  std::optional<PredictionColumns> columns;  ///< when the writer includes them.
  std::optional<PredictionErrors> errors;    ///< with a trial.
  std::optional<double> fitted_scale;        ///< the §6.1.2 constant, with fit_scale.
  std::optional<double> share_outside_identified_ranges;
  std::optional<double> released_at_s;
  std::optional<double> strength_at_start;
  std::optional<model::JointLimits> joint_limits;  ///< free swing: the stops used.
  friend bool operator==(const PredictionView&, const PredictionView&) = default;
};
/// {"prediction_id" (null until stored), "evaluation_id", "parameter_set_id",
///  "trial_id", "mode", "model", "initial_angle_deg", "initial_velocity_deg_s",
///  "samples", "sample_rate_hz" (with ≥ 2 samples), "columns": {"t_s",
///  "stim_ma", "angle_deg", "velocity_deg_s", "torque_nm", "activation"}
///  (when present), "errors" (null without a trial), "fitted_scale",
///  "share_outside_identified_ranges", "released_at_s", "strength_at_start",
///  "joint_limits": {"min_angle_deg", "max_angle_deg"} (or null)}.
nlohmann::json PredictionViewToJson(const PredictionView& view);
/// Needs "parameter_set_id" and a known "mode".
Result<PredictionView> PredictionViewFromJson(const nlohmann::json& json);

/// The errors of one trial under both sets of a pair.
struct TrialComparison {
  std::int64_t trial_id = 0;
  double a_error = 0.0;
  double b_error = 0.0;
  friend bool operator==(const TrialComparison&, const TrialComparison&) = default;
};

/// One subject's (leg's) pair: the same trials predicted by set a and set b.
struct PairComparison {
  std::int64_t a_parameter_set_id = 0;
  std::int64_t b_parameter_set_id = 0;
  std::int64_t subject_id = 0;
  std::int64_t leg_id = 0;
  std::vector<TrialComparison> trials;
  double a_error = 0.0;  ///< mean over the trials, in the metric's unit.
  double b_error = 0.0;
  friend bool operator==(const PairComparison&, const PairComparison&) = default;
};

/// A comparison job's result.
struct ComparisonResult {
  std::string metric;
  std::string unit;  ///< "deg", "N.m", or "1" (dimensionless metrics).
  std::vector<PairComparison> pairs;
  /// Unset when the t-test cannot be computed (fewer than 2 pairs, or all
  /// differences equal), `test_note` then says why.
  std::optional<model::PairedTTestResult> test;
  std::string test_note;
};
/// Field by field (model::PairedTTestResult has no comparison of its own).
bool operator==(const ComparisonResult& a, const ComparisonResult& b);
/// {"metric", "unit", "pairs": [{"a_parameter_set_id", "b_parameter_set_id",
///  "subject_id", "leg_id", "a_error", "b_error", "trials": [{"trial_id",
///  "a_error", "b_error"}]}], "t_test": {"mean_difference", "sd_difference",
///  "n", "t", "df", "p_value", "confidence", "t_critical", "significant"} or
///  null, "t_test_note" (null when empty)}.
nlohmann::json ComparisonResultToJson(const ComparisonResult& result);
/// Needs "metric" and "pairs" (each trial's "trial_id").
Result<ComparisonResult> ComparisonResultFromJson(const nlohmann::json& json);

/// A model check's verdict (docs/MODEL.md, "The model check"), from best to
/// worst; a set's verdict is its worst trial's.
enum class ModelVerdict {
  kGoodForControl,  ///< within the good thresholds on every fresh trial.
  kUseWithCare,     ///< within the care thresholds, or extrapolating much.
  kDoNotUse,        ///< a fresh trial beyond the care thresholds, or not predictable.
  kNoFreshTrials,   ///< nothing to judge on: record a prediction protocol first.
};
/// "good_for_control", "use_with_care", "do_not_use", "no_fresh_trials".
std::string_view ModelVerdictName(ModelVerdict verdict);
std::optional<ModelVerdict> ParseModelVerdict(std::string_view name);

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
  friend bool operator==(const ModelCheckThresholds&, const ModelCheckThresholds&) = default;
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
  friend bool operator==(const ModelCheckTrial&, const ModelCheckTrial&) = default;
};

/// A model-check job's result.
struct ModelCheck {
  std::int64_t parameter_set_id = 0;
  ModelVerdict verdict = ModelVerdict::kNoFreshTrials;
  std::string summary;  ///< one sentence for the clinician.
  ModelCheckThresholds thresholds;
  std::vector<ModelCheckTrial> trials;
  /// The set's fit warnings restated for a clinician, and the originals
  /// beside them.
  std::vector<std::string> warnings;
  std::vector<std::string> technical_warnings;
  friend bool operator==(const ModelCheck&, const ModelCheck&) = default;
};
/// {"parameter_set_id", "verdict", "summary", "thresholds": {"angle_good_deg",
///  "angle_care_deg", "torque_good_share", "torque_care_share",
///  "outside_care_share"}, "trials": [{"trial_id", "trial_name", "session_id",
///  "prediction_id", "quantity", "unit", "e_rms", "measured_range",
///  "share_outside_identified_ranges", "verdict", "explanation"}],
///  "warnings", "technical_warnings"}.
nlohmann::json ModelCheckToJson(const ModelCheck& check);
/// Needs "parameter_set_id" and a known "verdict" (also of each trial).
Result<ModelCheck> ModelCheckFromJson(const nlohmann::json& json);

}  // namespace fesbench::api
