#pragma once

/// @file
/// Model-gated stimulation (DESIGN.md §6, issue "Safety interlocks"): when
/// a parameter set exists for the leg, a prediction protocol's stimulation
/// is simulated first (model/simulate.h, free swing from the model's rest
/// angle) and the run refused if the predicted knee angle would leave the
/// subject's range of motion.

#include "api/status.h"
#include "model/parameter_set.h"
#include "server/protocols/plan.h"

namespace fesbench::server::protocols {

/// The predicted knee-angle excursion of a plan's free-swing trials.
struct PredictedExcursion {
  double rest_angle_deg = 90.0;  ///< start: τ_pta(θ) + τ_ptv(0) = 0 (90° if none in 10–110°).
  double min_angle_deg = 0.0;
  double max_angle_deg = 0.0;
};

/// The free-swing rest angle of a parameter set, deg (90 if none in 10–110°).
double ModelRestAngleDeg(const model::ParameterSet& params);

/// Simulates every decoupled trial of plan (envelope clamped to
/// plan.max_stim_ma) with params. kFailedPrecondition if the simulation
/// fails (invalid parameter set).
api::Result<PredictedExcursion> PredictExcursion(const Plan& plan,
                                                 const model::ParameterSet& params,
                                                 double pulse_rate_hz = 33.0);

/// OK unless the plan is a prediction protocol, the subject has a parameter
/// set, and the predicted angle leaves [min_angle_deg, max_angle_deg]:
/// then kFailedPrecondition naming the predicted excursion.
api::Status CheckModelGate(const Plan& plan, const SubjectContext& subject,
                           double pulse_rate_hz = 33.0);

}  // namespace fesbench::server::protocols
