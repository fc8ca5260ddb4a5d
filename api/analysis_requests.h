#pragma once

/// @file
/// The analysis requests as they travel (docs/API.md, "Jobs": `identifications`,
/// `predictions`, `comparisons`): one definition for the server that reads
/// them and the clients (CLI, study) that send them. Every physical
/// quantity names its unit in its key.
///
/// Reading is strict: unknown fields, wrong types, non-integral or
/// non-positive ids, out-of-range counts and names that are none of a
/// choice's are kInvalidArgument with the field path
/// ("breakpoints.active_angle[2]", "pairs[1].trial_ids[0]"). A method or
/// model name is parsed once, here, into the model's enumeration
/// (model/identify_*.h, model/parameter_set.h) and travels as that; each has
/// one wire spelling, the model's own name. Whether the values make sense
/// together (increasing breakpoints, no model twice, at least one pair) is
/// the services' validation (server/services), which runs on the parsed
/// value.
///
/// Identification request:
///   {"session_id": 3 | "trial_ids": [..], "method": "thesis" | "rapid",
///    "irc_method": "ramp_correlation", "passive_method": "simultaneous",
///    "contraction_order": 3, "pole_method": "peak", "models": ["full", ..],
///    "breakpoints": {"passive_angle": 11 | [deg..], "passive_velocity": ..,
///                    "active_angle": .., "active_velocity": ..},
///    "inertia_kgm2": 0.36, "torque_angle_parameter_set_id": 4}
/// Prediction request:
///   {"parameter_set_id": 1, "trial_id": 2} or
///   {"parameter_set_id": 1, "stimulus": {"generator": "prediction_step",
///    "params": {"threshold_ma": 20, ..}}, "mode": "free_swing" | "isometric",
///    "initial_angle_deg": 90, "initial_velocity_deg_s": 0, "duration_s": 5}
/// Comparison request:
///   {"pairs": [{"a_parameter_set_id": 1, "b_parameter_set_id": 2,
///               "trial_ids": [5, 6]}, ..],
///    "metric": "e_rms", "confidence": 0.95}

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/status.h"
#include "model/identify_common.h"
#include "model/identify_isometric.h"
#include "model/identify_passive.h"
#include "model/parameter_set.h"
#include "model/stimulus_generators.h"

namespace fesbench::api {

/// Breakpoints of the fitted curves: a count over the visited range or
/// explicit abscissae (model::BreakpointSpec); unset = the method's default
/// (simultaneous τ_pta 11, τ_ptv 9; free swing τ_ptv 4; active 11 and 11;
/// rapid 9, 7, 7, 7).
struct IdentificationBreakpoints {
  std::optional<model::BreakpointSpec> passive_angle;     ///< τ_pta, deg.
  std::optional<model::BreakpointSpec> passive_velocity;  ///< τ_ptv, deg/s.
  std::optional<model::BreakpointSpec> active_angle;      ///< f_ata, deg.
  std::optional<model::BreakpointSpec> active_velocity;   ///< f_atv, deg/s.
};

struct IdentificationRequest {
  /// Exactly one of session_id and trial_ids (all of one subject and leg).
  std::optional<std::int64_t> session_id;
  std::vector<std::int64_t> trial_ids;
  /// "thesis" (the chapter 4 methods below), "rapid" (§7.4.1, from the
  /// rapid_* trials) or "passive" (the passive block alone from unstimulated
  /// free swings, e.g. a pendulum test; docs/MODEL.md).
  model::IdentificationMethod method = model::IdentificationMethod::kThesis;
  /// "step", "impulse", "ramp_correlation", "ramp_deconvolution_ideal",
  /// "ramp_deconvolution_measured".
  model::IrcMethod irc_method = model::IrcMethod::kRampCorrelation;
  /// "sequential", "simultaneous", "free_swing" (method passive and rapid:
  /// free_swing).
  model::PassiveMethod passive_method = model::PassiveMethod::kSimultaneous;
  int contraction_order = 3;  ///< 2, 3, or 0 = the better-fitting order.
  model::PoleMethod pole_method = model::PoleMethod::kPeak;  ///< "peak" or "least_squares".
  /// Model variants to fit and store, "full" and/or the simplified ones
  /// (model::ModelKindName). One stored version each.
  std::vector<model::ModelKind> models = {model::ModelKind::kFull};
  IdentificationBreakpoints breakpoints;
  /// Limb inertia, kg·m²: sequential and rapid. Unset: the subject's
  /// anthropometrics (Eq. 4.13: weight, shank length), else (rapid) the
  /// leg's latest parameter set.
  std::optional<double> inertia_kgm2;
  /// m·g·l of the shank and foot, N·m (method passive, when inertia_kgm2 is
  /// not given): gravity's moment fixes the torque scale of the swings and
  /// J is identified from their period. Unset: from the subject's weight
  /// and shank length (Winter's segment, MODEL.md).
  std::optional<double> gravity_moment_nm;
  /// free_swing without a passive_positions trial: the stored set whose
  /// τ_pta is used (default: the leg's latest).
  std::optional<std::int64_t> torque_angle_parameter_set_id;
};

/// The wire names of the identification choices, each once, in the model's
/// order: what IdentificationRequestFromJson accepts and a client offers
/// (the CLI's --method and --passive-method).
std::vector<std::string> IdentificationMethodNames();
std::vector<std::string> IrcMethodNames();
std::vector<std::string> PassiveMethodNames();
std::vector<std::string> PoleMethodNames();

enum class PredictionMode { kFreeSwing, kIsometric };
/// "free_swing", "isometric".
std::string_view PredictionModeName(PredictionMode mode);
/// The mode of a name, nullopt for any other.
std::optional<PredictionMode> ParsePredictionMode(std::string_view name);

/// A named stimulus generator (model/stimulus_generators.h) and its values.
struct StimulusSpec {
  std::string generator;
  model::GeneratorParams params = {};
};

struct PredictionRequest {
  std::int64_t parameter_set_id = 0;
  /// Exactly one of trial_id (replay its stimulation from its measured
  /// initial state and compare) and stimulus.
  std::optional<std::int64_t> trial_id;
  std::optional<StimulusSpec> stimulus;
  /// Stimulus: default free swing. Trial: default its protocol's mode.
  std::optional<PredictionMode> mode;
  /// Stimulus only. Free swing θ(0), deg, −30–180 (default: the passive rest
  /// angle, else 90°); isometric lock angle, deg (default 90°).
  std::optional<double> initial_angle_deg;
  double initial_velocity_deg_s = 0.0;  ///< stimulus free swing θ̇(0), |·| ≤ 2000 deg/s.
  std::optional<double> duration_s;     ///< stimulus only; default: the envelope's length.
  /// Isometric trial only: scale the predicted torque by the least-squares
  /// constant before the errors, as the isometric IRC comparisons of §6.1.2
  /// and §6.2 do ("the maximum isometric torque output was determined by
  /// scaling the simulation result by a constant to get a best fit").
  bool fit_scale = false;
};

struct ComparisonPair {
  std::int64_t a_parameter_set_id = 0;
  std::int64_t b_parameter_set_id = 0;
  std::vector<std::int64_t> trial_ids;  ///< 1–50 trials of the sets' leg.
};

struct ComparisonRequest {
  std::vector<ComparisonPair> pairs;  ///< 1–200 (the t-test needs ≥ 2).
  /// "e_rms" (Eq. 6.9), "e_abs" (Eq. 6.10), "normalised_rms" (Eq. 6.1),
  /// "e_ave" (Eq. 6.2).
  std::string metric = "e_rms";
  double confidence = 0.95;  ///< of the two-sided critical value, in (0, 1).
};

Result<IdentificationRequest> IdentificationRequestFromJson(const nlohmann::json& json);
nlohmann::json IdentificationRequestToJson(const IdentificationRequest& request);

Result<PredictionRequest> PredictionRequestFromJson(const nlohmann::json& json);
nlohmann::json PredictionRequestToJson(const PredictionRequest& request);

Result<ComparisonRequest> ComparisonRequestFromJson(const nlohmann::json& json);
nlohmann::json ComparisonRequestToJson(const ComparisonRequest& request);

}  // namespace fesbench::api
