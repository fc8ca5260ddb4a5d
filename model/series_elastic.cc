#include "model/series_elastic.h"

#include <Eigen/Core>
#include <cmath>
#include <stdexcept>
#include <string>

#include "model/joint_model.h"
#include "model/units.h"

namespace fesbench::model {
namespace {

void ValidateSeriesElastic(const SeriesElasticParams& se) {
  if (!std::isfinite(se.kse_nm_per_deg) || !(se.kse_nm_per_deg > 0.0)) {
    throw std::invalid_argument("series elastic: kse_nm_per_deg must be finite and > 0");
  }
  if (!std::isfinite(se.ce_inertia_kgm2) || !(se.ce_inertia_kgm2 > 0.0)) {
    throw std::invalid_argument("series elastic: ce_inertia_kgm2 must be finite and > 0");
  }
  if (!std::isfinite(se.se_damping_nm_s_per_deg) || se.se_damping_nm_s_per_deg < 0.0) {
    throw std::invalid_argument("series elastic: se_damping_nm_s_per_deg must be finite and >= 0");
  }
}

void ValidateCommon(const ParameterSet& params, const PulseTrain& pulses, double angle_deg,
                    const char* angle_field) {
  ValidatePulseTrain(pulses);
  ValidateContraction(params.contraction);
  if (params.irc.empty()) throw std::invalid_argument("simulation: irc is empty");
  if (!std::isfinite(angle_deg) || angle_deg < 0.0 || angle_deg > 180.0) {
    throw std::invalid_argument(std::string("simulation: ") + angle_field +
                                " must be within 0-180 deg, got " + std::to_string(angle_deg));
  }
}

SeriesElasticResult MakeResult(std::size_t n, double rate_hz, ModelKind kind,
                               const PulseTrain& pulses, double pulse_rate_hz) {
  SeriesElasticResult r;
  SimulationResult& j = r.joint;
  j.model = kind;
  j.t_s.resize(n);
  for (std::size_t i = 0; i < n; ++i) j.t_s[i] = static_cast<double>(i) / rate_hz;
  for (auto* col : {&j.angle_deg, &j.velocity_deg_s, &j.accel_deg_s2, &j.torque_nm, &j.activation,
                    &r.ce_angle_deg, &r.ce_velocity_deg_s, &r.se_torque_nm}) {
    col->assign(n, 0.0);
  }
  j.stim_ma = StimulusColumn(pulses, pulse_rate_hz, j.t_s);
  return r;
}

// τ_se = K_se·(θ − θ_ce) + B_se·(θ̇ − θ̇_ce), N·m.
double SeTorque(const SeriesElasticParams& se, double angle_deg, double velocity_deg_s,
                double ce_angle_deg, double ce_velocity_deg_s) {
  return se.kse_nm_per_deg * (angle_deg - ce_angle_deg) +
         se.se_damping_nm_s_per_deg * (velocity_deg_s - ce_velocity_deg_s);
}

// Eq. 3.12 (our signs): m·θ̈_ce = τ_se − f_stim·τ_scale·f_ata(θ_ce)·f_atv(θ̇_ce); deg/s².
double CeAccel(const JointModel& model, const SeriesElasticParams& se, double se_torque_nm,
               double ce_angle_deg, double ce_velocity_deg_s, double activation) {
  const double ce_torque_nm = activation * model.ActiveGain(ce_angle_deg, ce_velocity_deg_s);
  return RadToDeg((se_torque_nm - ce_torque_nm) / se.ce_inertia_kgm2);
}

}  // namespace

SimulationOptions DefaultSeriesElasticOptions() {
  SimulationOptions o;
  o.integrator = IntegratorKind::kAdaptive;
  o.tolerances = {1e-8, 1e-9, 1e-12, 0.005, 50'000'000};
  return o;
}

SeriesElasticResult SimulateSeriesElasticFreeSwing(const ParameterSet& params,
                                                   const SeriesElasticParams& se,
                                                   const PulseTrain& pulses,
                                                   const SimulationOptions& options) {
  ValidateSeriesElastic(se);
  ValidateCommon(params, pulses, options.initial_angle_deg, "initial_angle_deg");
  if (!std::isfinite(options.initial_velocity_deg_s)) {
    throw std::invalid_argument("simulation: initial_velocity_deg_s must be finite");
  }
  const std::size_t n = detail::ValidateOptions(options, detail::DefaultDuration(pulses));
  const JointModel model = JointModel::FromParameters(params, options.model_kind);
  SeriesElasticResult r =
      MakeResult(n, options.output_rate_hz, model.kind(), pulses, options.pulse_rate_hz);

  // State (θ, θ̇, θ_ce, θ̇_ce) in deg, deg/s.
  using State = Eigen::Vector4d;
  const auto accel = [&](const State& x, double activation) {
    const double tse = SeTorque(se, x[0], x[1], x[2], x[3]);
    // Eq. 3.14 (our signs): J·θ̈ = −τ_pta(θ) − τ_ptv(θ̇) − τ_se.
    const double joint =
        RadToDeg((-model.PassiveAngleTorque(x[0]) - model.PassiveVelocityTorque(x[1]) - tse) /
                 model.inertia_kgm2());
    return std::pair<double, double>(joint, CeAccel(model, se, tse, x[2], x[3], activation));
  };
  const auto rhs = [&](double /*t*/, const State& x, double activation) {
    const auto [aj, ace] = accel(x, activation);
    return State(x[1], aj, x[3], ace);
  };
  const auto record = [&](std::size_t i, double /*t*/, const State& x, double activation) {
    r.joint.angle_deg[i] = x[0];
    r.joint.velocity_deg_s[i] = x[1];
    r.joint.accel_deg_s2[i] = accel(x, activation).first;
    r.joint.activation[i] = activation;
    r.ce_angle_deg[i] = x[2];
    r.ce_velocity_deg_s[i] = x[3];
    r.se_torque_nm[i] = SeTorque(se, x[0], x[1], x[2], x[3]);
  };
  const IntegratorSettings settings{options.integrator, options.step_s, options.tolerances};
  IntegratorWorkspace ws;
  const double th0 = options.initial_angle_deg, w0 = options.initial_velocity_deg_s;
  detail::RunPulseDriven(rhs, record, State(th0, w0, th0, w0), params.contraction, params.irc,
                         pulses, options.pulse_rate_hz, options.output_rate_hz, n, settings, ws);
  r.joint.stats = ws.stats;
  return r;
}

SeriesElasticResult SimulateSeriesElasticIsometric(const ParameterSet& params,
                                                   const SeriesElasticParams& se,
                                                   const PulseTrain& pulses, double angle_deg,
                                                   const SimulationOptions& options) {
  ValidateSeriesElastic(se);
  ValidateCommon(params, pulses, angle_deg, "angle_deg");
  const std::size_t n = detail::ValidateOptions(options, detail::DefaultDuration(pulses));
  const JointModel model = JointModel::FromParameters(params, options.model_kind);
  SeriesElasticResult r =
      MakeResult(n, options.output_rate_hz, model.kind(), pulses, options.pulse_rate_hz);

  // State (θ_ce, θ̇_ce); the joint is held at θ₀ with θ̇ = 0.
  using State = Eigen::Vector2d;
  const double passive_nm = model.PassiveAngleTorque(angle_deg) + model.PassiveVelocityTorque(0.0);
  const auto rhs = [&](double /*t*/, const State& x, double activation) {
    const double tse = SeTorque(se, angle_deg, 0.0, x[0], x[1]);
    return State(x[1], CeAccel(model, se, tse, x[0], x[1], activation));
  };
  const auto record = [&](std::size_t i, double /*t*/, const State& x, double activation) {
    const double tse = SeTorque(se, angle_deg, 0.0, x[0], x[1]);
    r.joint.angle_deg[i] = angle_deg;
    r.joint.activation[i] = activation;
    r.joint.torque_nm[i] = passive_nm + tse;  // the brace holds the SE's pull
    r.ce_angle_deg[i] = x[0];
    r.ce_velocity_deg_s[i] = x[1];
    r.se_torque_nm[i] = tse;
  };
  const IntegratorSettings settings{options.integrator, options.step_s, options.tolerances};
  IntegratorWorkspace ws;
  detail::RunPulseDriven(rhs, record, State(angle_deg, 0.0), params.contraction, params.irc, pulses,
                         options.pulse_rate_hz, options.output_rate_hz, n, settings, ws);
  r.joint.stats = ws.stats;
  return r;
}

}  // namespace fesbench::model
