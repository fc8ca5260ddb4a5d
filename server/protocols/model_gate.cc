#include "server/protocols/model_gate.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "model/simulate.h"

namespace fesbench::server::protocols {

double ModelRestAngleDeg(const model::ParameterSet& params) {
  const auto net = [&](double th) {
    return params.passive.torque_angle(th) + params.passive.torque_velocity(0.0);
  };
  if (params.passive.torque_angle.empty() || params.passive.torque_velocity.empty()) return 90.0;
  // The stable zero (net torque rising through 0) nearest 90°.
  double best = 90.0, best_dist = 1e9;
  for (double th = 10.0; th < 110.0; th += 0.25) {
    const double a = net(th), b = net(th + 0.25);
    if (a <= 0.0 && b > 0.0) {
      const double z = th + 0.25 * (-a) / (b - a);
      if (std::abs(z - 90.0) < best_dist) {
        best = z;
        best_dist = std::abs(z - 90.0);
      }
    }
  }
  return best;
}

api::Result<PredictedExcursion> PredictExcursion(const Plan& plan,
                                                 const model::ParameterSet& params,
                                                 double pulse_rate_hz) {
  PredictedExcursion out;
  out.rest_angle_deg = ModelRestAngleDeg(params);
  out.min_angle_deg = out.max_angle_deg = out.rest_angle_deg;
  try {
    for (std::size_t k = 0; k < plan.trials.size(); ++k) {
      if (plan.trials[k].mode != MotorMode::kDecoupled) continue;
      model::SampledSignal env = TrialEnvelope(plan, static_cast<int>(k));
      if (env.values.empty()) continue;
      for (double& u : env.values) u = std::clamp(u, 0.0, plan.max_stim_ma);
      model::SimulationOptions o;
      o.initial_angle_deg = out.rest_angle_deg;
      o.duration_s = env.EndTime();
      o.pulse_rate_hz = pulse_rate_hz;
      const model::SimulationResult sim =
          model::SimulateFreeSwing(params, model::PulsesFromEnvelope(env, pulse_rate_hz), o);
      const auto [lo, hi] = std::minmax_element(sim.angle_deg.begin(), sim.angle_deg.end());
      out.min_angle_deg = std::min(out.min_angle_deg, *lo);
      out.max_angle_deg = std::max(out.max_angle_deg, *hi);
    }
  } catch (const std::exception& e) {
    return api::Status::FailedPrecondition(std::string("model-gated stimulation: ") + e.what());
  }
  return out;
}

api::Status CheckModelGate(const Plan& plan, const SubjectContext& subject, double pulse_rate_hz) {
  if (plan.kind != ProtocolKind::kPrediction || !subject.parameter_set) return api::Status::Ok();
  const api::Result<PredictedExcursion> ex =
      PredictExcursion(plan, *subject.parameter_set, pulse_rate_hz);
  if (!ex.ok()) return ex.status();
  if (ex->min_angle_deg < subject.min_angle_deg || ex->max_angle_deg > subject.max_angle_deg) {
    std::ostringstream os;
    os.precision(4);
    os << "model-gated stimulation: predicted knee angle " << ex->min_angle_deg << "–"
       << ex->max_angle_deg << " deg leaves the range of motion " << subject.min_angle_deg << "–"
       << subject.max_angle_deg << " deg";
    return api::Status::FailedPrecondition(os.str());
  }
  return api::Status::Ok();
}

}  // namespace fesbench::server::protocols
