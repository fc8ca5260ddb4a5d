#pragma once

/// @file
/// Model-gated stimulation (docs/SAFETY.md, "Model gate": the gate
/// predicts as predictions do): when a parameter set exists for the leg, every free-swing
/// trial of a prediction protocol is simulated first with the SAME free-swing
/// simulation as POST /predictions (SimulateStimulatedSwing: start at the
/// model's passive rest angle, pulses from the envelope at the bench's pulse
/// rate, the range of motion as hard stops) and the run is refused only if
/// the predicted knee hits a stop faster than the bench's impact limit
/// (BenchLimits::max_stop_impact_deg_s). A set whose simulation diverges is
/// reported as unusable for this input, not as a range-of-motion refusal.

#include <optional>
#include <string>
#include <vector>

#include "api/status.h"
#include "model/parameter_set.h"
#include "model/signal.h"
#include "model/simulate.h"
#include "server/protocols/plan.h"

namespace fesbench::server::protocols {

/// Default impact-speed limit at a joint stop, deg/s: the bench's default
/// (BenchLimits::max_stop_impact_deg_s, where the choice is explained).
inline constexpr double kDefaultMaxStopImpactDegS = kDefaultBenchMaxStopImpactDegS;

/// Start angle of a free-swing prediction without a measured start (POST
/// /predictions and the gate): the passive rest angle (τ_pta(θ) = 0,
/// model::PassiveRestAngle), else the reference angle 90°.
double FreeSwingStartAngleDeg(const model::ParameterSet& params);

/// THE free-swing simulation of POST /predictions and the model gate:
/// model::SimulateFreeSwing of `pulses` with `options` (stops in
/// options.joint_limits). Throws what the model throws.
model::SimulationResult SimulateStimulatedSwing(const model::ParameterSet& params,
                                                const model::PulseTrain& pulses,
                                                const model::SimulationOptions& options);

/// The pulses of a stimulation envelope (mA) at the stimulator's pulse rate:
/// model::PulsesFromEnvelope, the pulse clock running continuously from the
/// envelope's t = 0 (a trial's start), as the bench delivers a plan's trial
/// (the runner restarts the clock at each trial, docs/MODEL.md).
model::PulseTrain EnvelopePulses(const model::SampledSignal& envelope_ma, double pulse_rate_hz);

/// The knee arriving at a stop in a simulated trial.
struct StopImpact {
  std::string trial;  ///< the plan's trial name.
  double t_s = 0.0;   ///< time of arrival in the trial, s.
  std::optional<double>
      onset_s;  ///< start of the stimulation burst that drove it (none: no stimulation before).
  bool extension = true;  ///< the extension stop (min angle) or the flexion stop (max).
  double stop_deg = 0.0;
  double speed_deg_s = 0.0;  ///< speed just before arrival.
};

/// What the gate predicts for a plan's free-swing trials.
struct GatePrediction {
  double start_angle_deg = 90.0;  ///< FreeSwingStartAngleDeg (inside the stops).
  double min_angle_deg = 0.0;     ///< predicted excursion over all trials.
  double max_angle_deg = 0.0;
  std::vector<StopImpact> impacts;  ///< every arrival at a stop, in trial order.
};

/// Simulates every decoupled trial of `plan` (envelope clamped to
/// plan.max_stim_ma) from the start angle within `stops`. kFailedPrecondition
/// "cannot simulate this input: …" when the simulation throws, its state
/// turns non-finite or the knee speed exceeds 10⁴ deg/s (the parameter set
/// diverges on this input).
api::Result<GatePrediction> PredictPlanSwing(const Plan& plan, const model::ParameterSet& params,
                                             const model::JointLimits& stops, double pulse_rate_hz);

/// kFailedPrecondition (NoApprovedSetMessage) for a prediction protocol or
/// daily check on a leg whose sets all await a clinician's approval
/// (subject.sets_await_approval). Otherwise OK unless the plan is a
/// prediction protocol, the subject has an approved parameter set, and
/// either the set cannot simulate the input (kFailedPrecondition
/// "parameter set N cannot simulate this input: …") or the knee is predicted
/// to hit a stop of the subject's range of motion faster than
/// `max_impact_speed_deg_s` (kFailedPrecondition: "model-gated stimulation:
/// the stimulation from 2.4 s of trial prediction_step drives the knee into
/// the extension stop (10°) at 140 deg/s, above the bench's 90 deg/s limit").
api::Status CheckModelGate(const Plan& plan, const SubjectContext& subject,
                           double pulse_rate_hz = 33.0,
                           double max_impact_speed_deg_s = kDefaultMaxStopImpactDegS);

}  // namespace fesbench::server::protocols
