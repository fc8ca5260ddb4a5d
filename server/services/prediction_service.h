#pragma once

/// @file
/// Prediction (docs/MODEL.md, "Evaluation"; docs/API.md; thesis §5.4.5,
/// ch. 6): simulates a stored parameter set on a named stimulus generator
/// or on a stored trial's stimulation and initial state, and — against a
/// measured trial — reports E_RMS and E_ABS (Eqs. 6.9, 6.10), the
/// normalised RMS (Eq. 6.1) and E_AVE (Eq. 6.2). Predict stores the
/// prediction, its evaluation and an audit entry in one transaction
/// (storage::PredictionRepository).
///
/// Modes: free swing (the angle is predicted and compared, deg) and
/// isometric (the torque, N·m, offset removed at rest as the bench records
/// it, §5.3: the prediction's value before any activation and the mean of
/// the measured samples before the first stimulation are subtracted).
/// A trial's mode is its protocol's (isometric_* and rapid_isometric_* are
/// locked; a trial whose angle moves less than 0.5° is isometric too);
/// motor trials (passive_*) are refused.
///
/// Thread-safe (no mutable state besides the database).

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "api/analysis_requests.h"
#include "api/analysis_results.h"
#include "api/status.h"
#include "model/parameter_set.h"
#include "model/simulate.h"
#include "model/stimulus_generators.h"
#include "server/services/actor.h"
#include "storage/database.h"

namespace fesbench::server::services {

struct PredictionConfig {
  double max_duration_s = 600.0;              ///< longest prediction, s.
  double pulse_rate_hz = 33.0;                ///< stimulator pulse rate, Hz.
  double output_rate_hz = 200.0;              ///< sample rate of stimulus predictions, Hz.
  double normalised_exclude_fraction = 0.05;  ///< Eq. 6.1 exclusion (evaluation.h).
  /// The bench's range of motion: free-swing predictions stop at it, as the
  /// knee does (model/simulate.h JointLimits). Unset: unbounded.
  std::optional<model::JointLimits> joint_limits = model::JointLimits{};
  /// The strength state of predictions on a stored trial (docs/MODEL.md,
  /// "The strength at a trial's start"): when set, the active torque is
  /// multiplied by s(t)/s_ref, s propagated through the pulses of the
  /// session's earlier trials and the rests between them to the trial's
  /// start, then through the trial's own pulses; s_ref the strength of the
  /// set's free-swing trials in that session (1 if none). Unset (the
  /// default): s ≡ 1, the thesis's time-invariant model — on the simulated
  /// legs the literature prior made predictions worse (docs/MODEL.md).
  std::optional<model::StrengthParameters> strength;
};

/// The request's wire form (api/analysis_requests.h).
using PredictionMode = api::PredictionMode;
using api::PredictionModeName;
using StimulusSpec = api::StimulusSpec;
using PredictionRequest = api::PredictionRequest;

/// The errors of a prediction against a measured trial (ch. 6; the wire
/// form of api/analysis_results.h).
using PredictionErrors = api::PredictionErrors;

struct PredictionResult {
  std::int64_t prediction_id = 0;             ///< 0 when not stored.
  std::optional<std::int64_t> evaluation_id;  ///< with a trial, once stored.
  std::int64_t parameter_set_id = 0;
  std::optional<std::int64_t> trial_id;
  PredictionMode mode = PredictionMode::kFreeSwing;
  std::string model;  ///< the variant simulated.
  double initial_angle_deg = 0.0;
  double initial_velocity_deg_s = 0.0;
  /// Predicted columns at the output rate (trial: the trial's rate); the
  /// isometric torque offset-removed.
  model::SimulationResult predicted;
  std::optional<PredictionErrors> errors;          ///< with a trial.
  std::optional<double> fitted_scale;              ///< the §6.1.2 constant, with fit_scale.
  std::optional<model::JointLimits> joint_limits;  ///< free swing: the stops used.
  /// Free swing: the share (0–1) of predicted samples outside the ranges the
  /// set's curves were identified over (model::ShareOutsideIdentifiedRanges);
  /// unset if the set records none.
  std::optional<double> share_outside_identified_ranges;
  /// A pendulum test held before its release (model::PendulumReleaseIndex):
  /// the time into the trial, s, from which it was predicted and compared.
  std::optional<double> released_at_s;
  /// With PredictionConfig::strength, on a bench trial with a start time:
  /// s/s_ref at the trial's start, the factor the set's active torque
  /// started with (1: as strong as when the set was identified).
  std::optional<double> strength_at_start;
};

/// Checks the request alone: kInvalidArgument naming the field.
api::Status ValidatePredictionRequest(const PredictionRequest& request,
                                      const PredictionConfig& config = {});

class PredictionService {
 public:
  /// `db` must outlive the service.
  explicit PredictionService(storage::Database& db, PredictionConfig config = {});

  /// Simulates and evaluates without storing anything. kNotFound for an
  /// unknown parameter set or trial; kInvalidArgument naming the field for
  /// bad input (durations over max_duration_s, unknown generator or
  /// parameter, angles outside −30–180°); kFailedPrecondition when the trial
  /// lacks a needed channel or the simulation fails (e.g. diverges).
  api::Result<PredictionResult> Compute(const PredictionRequest& request) const;

  /// Compute, then stores the prediction (and, with a trial, its
  /// evaluation) and an audit entry in one transaction. Analysts and admins
  /// only (kPermissionDenied).
  api::Result<PredictionResult> Predict(const Actor& actor, const PredictionRequest& request);

  const PredictionConfig& config() const { return config_; }

 private:
  storage::Database& db_;
  PredictionConfig config_;
};

}  // namespace fesbench::server::services
