#include "server/protocols/model_gate.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "api/model_call.h"
#include "model/evaluation.h"

namespace fesbench::server::protocols {
namespace {

// The gate samples finely so the speed before a stop is the speed at impact
// within one 1 ms integration step.
constexpr double kGateOutputRateHz = 1000.0;
// A sample this close to a stop is at it (the stop projection puts it exactly there).
constexpr double kAtStopDeg = 1e-6;
// No knee swings this fast (voluntary and FES swings stay below ~1000 deg/s):
// a prediction faster than this is a numerical blow-up, not a motion.
constexpr double kDivergedSpeedDegS = 1e4;

std::string Format(double v, int precision = 3) {
  std::ostringstream os;
  os.precision(precision);
  os << v;
  return os.str();
}

// Start of the stimulation burst in effect at time t (the last rise from 0).
std::optional<double> BurstOnset(const model::SampledSignal& env, double t) {
  if (env.values.empty() || !(env.rate_hz > 0.0)) return std::nullopt;
  auto i = static_cast<std::size_t>(
      std::min<double>(std::floor(t * env.rate_hz), static_cast<double>(env.values.size() - 1)));
  // Back to the latest sample with stimulation at or before t …
  while (i > 0 && env.values[i] <= 0.0) --i;
  if (env.values[i] <= 0.0) return std::nullopt;
  // … then to the start of that burst.
  while (i > 0 && env.values[i - 1] > 0.0) --i;
  return static_cast<double>(i) / env.rate_hz;
}

}  // namespace

double FreeSwingStartAngleDeg(const model::ParameterSet& params) {
  // No passive curves or no stable rest angle: the reference angle.
  if (params.passive.torque_angle.empty() || params.passive.torque_velocity.empty()) {
    return model::kReferenceAngleDeg;
  }
  return model::FindPassiveRestAngle(params.passive).value_or(model::kReferenceAngleDeg);
}

model::SimulationResult SimulateStimulatedSwing(const model::ParameterSet& params,
                                                const model::PulseTrain& pulses,
                                                const model::SimulationOptions& options) {
  return model::SimulateFreeSwing(params, pulses, options);
}

model::PulseTrain EnvelopePulses(const model::SampledSignal& envelope_ma, double pulse_rate_hz) {
  return model::PulsesFromEnvelope(envelope_ma, pulse_rate_hz);
}

api::Result<GatePrediction> PredictPlanSwing(const Plan& plan, const model::ParameterSet& params,
                                             const model::JointLimits& stops,
                                             double pulse_rate_hz) {
  GatePrediction out;
  out.start_angle_deg =
      std::clamp(FreeSwingStartAngleDeg(params), stops.min_angle_deg, stops.max_angle_deg);
  out.min_angle_deg = out.max_angle_deg = out.start_angle_deg;
  for (std::size_t k = 0; k < plan.trials.size(); ++k) {
    if (plan.trials[k].mode != MotorMode::kDecoupled) continue;
    const std::string& name = plan.trials[k].name;
    model::SampledSignal env = TrialEnvelope(plan, static_cast<int>(k));
    if (env.values.empty()) continue;
    for (double& u : env.values) u = std::clamp(u, 0.0, plan.max_stim_ma);
    model::SimulationOptions o;
    o.initial_angle_deg = out.start_angle_deg;
    o.duration_s = env.EndTime();
    o.pulse_rate_hz = pulse_rate_hz;
    o.output_rate_hz = kGateOutputRateHz;
    o.joint_limits = stops;
    api::Result<model::SimulationResult> simulated = api::CallModel(
        [&] { return SimulateStimulatedSwing(params, EnvelopePulses(env, pulse_rate_hz), o); });
    if (!simulated.ok()) {
      return api::Status::FailedPrecondition("cannot simulate this input: trial " + name + ": " +
                                             simulated.status().message());
    }
    const model::SimulationResult& sim = *simulated;
    for (std::size_t i = 0; i < sim.size(); ++i) {
      const double th = sim.angle_deg[i];
      const double v = i < sim.velocity_deg_s.size() ? sim.velocity_deg_s[i] : 0.0;
      if (!std::isfinite(th) || !std::isfinite(v)) {
        return api::Status::FailedPrecondition(
            "cannot simulate this input: the predicted knee state becomes non-finite at " +
            Format(sim.t_s[i]) + " s of trial " + name);
      }
      if (std::abs(v) > kDivergedSpeedDegS) {
        return api::Status::FailedPrecondition(
            "cannot simulate this input: the predicted knee speed reaches " + Format(std::abs(v)) +
            " deg/s at " + Format(sim.t_s[i]) + " s of trial " + name +
            " (numerically unstable: more than " + Format(kDivergedSpeedDegS) + " deg/s)");
      }
      out.min_angle_deg = std::min(out.min_angle_deg, th);
      out.max_angle_deg = std::max(out.max_angle_deg, th);
      if (i == 0) continue;
      const double prev = sim.angle_deg[i - 1];
      const bool at_min = th <= stops.min_angle_deg + kAtStopDeg;
      const bool at_max = th >= stops.max_angle_deg - kAtStopDeg;
      const bool was_min = prev <= stops.min_angle_deg + kAtStopDeg;
      const bool was_max = prev >= stops.max_angle_deg - kAtStopDeg;
      if ((at_min && !was_min) || (at_max && !was_max)) {
        StopImpact impact;
        impact.trial = name;
        impact.t_s = sim.t_s[i];
        impact.extension = at_min;
        impact.stop_deg = at_min ? stops.min_angle_deg : stops.max_angle_deg;
        const double dt = sim.t_s[i] - sim.t_s[i - 1];
        impact.speed_deg_s = std::max(std::abs(sim.velocity_deg_s[i - 1]),
                                      dt > 0.0 ? std::abs(th - prev) / dt : 0.0);
        impact.onset_s = BurstOnset(env, sim.t_s[i]);
        out.impacts.push_back(std::move(impact));
      }
    }
  }
  return out;
}

api::Status CheckModelGate(const Plan& plan, const SubjectContext& subject, double pulse_rate_hz,
                           double max_impact_speed_deg_s) {
  const bool gated = plan.kind == ProtocolKind::kPrediction || plan.kind == ProtocolKind::kDailyCheck;
  if (!gated) return api::Status::Ok();
  // docs/SAFETY.md, model gate: only a set a clinician approved gates; a
  // leg whose sets all await approval is not let through ungated.
  if (!subject.parameter_set && subject.sets_await_approval) {
    return api::Status::FailedPrecondition(NoApprovedSetMessage("model-gated stimulation"));
  }
  if (!subject.parameter_set) return api::Status::Ok();
  const std::string set = subject.parameter_set_id
                              ? "parameter set " + std::to_string(*subject.parameter_set_id)
                              : std::string("the leg's parameter set");
  const api::Result<GatePrediction> p = PredictPlanSwing(
      plan, *subject.parameter_set,
      model::JointLimits{subject.min_angle_deg, subject.max_angle_deg}, pulse_rate_hz);
  if (!p.ok()) return api::Status::FailedPrecondition(set + " " + p.status().message());
  for (const StopImpact& i : p->impacts) {
    if (i.speed_deg_s <= max_impact_speed_deg_s) continue;
    std::ostringstream os;
    os << "model-gated stimulation (" << set << "): ";
    if (i.onset_s) {
      os << "the stimulation from " << Format(*i.onset_s) << " s of trial " << i.trial;
    } else {
      os << "the swing before any stimulation in trial " << i.trial;
    }
    os << " drives the knee into the " << (i.extension ? "extension" : "flexion") << " stop ("
       << Format(i.stop_deg) << "°) at " << Format(i.speed_deg_s) << " deg/s (at " << Format(i.t_s)
       << " s), above the bench's " << Format(max_impact_speed_deg_s)
       << " deg/s limit; lower the amplitude or shorten the bursts";
    return api::Status::FailedPrecondition(os.str());
  }
  return api::Status::Ok();
}

}  // namespace fesbench::server::protocols
