#include "model/tracking.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>

#include "model/units.h"

namespace fesbench::model {
namespace {

void Require(bool ok, const std::string& message) {
  if (!ok) throw std::invalid_argument(message);
}

// One step of the critically damped state-variable filter ÿ = ω²(x − y) − 2ω·ẏ
// (semi-implicit Euler, stable for ω·dt < 1); returns ÿ.
double FilterStep(std::array<double, 2>& state, double input, double omega, double dt_s) {
  const double accel = omega * omega * (input - state[0]) - 2.0 * omega * state[1];
  state[1] += dt_s * accel;
  state[0] += dt_s * state[1];
  return accel;
}

// Seconds of samples the estimator waits for its filters to settle.
constexpr double kEstimatorWarmupS = 0.5;

}  // namespace

std::string_view ControllerKindName(ControllerKind kind) {
  switch (kind) {
    case ControllerKind::kPid:
      return "pid";
    case ControllerKind::kInverseModel:
      return "inverse_model";
    case ControllerKind::kAdaptive:
      return "adaptive";
  }
  return "pid";
}

std::optional<ControllerKind> ControllerKindOf(std::string_view name) {
  for (ControllerKind k :
       {ControllerKind::kPid, ControllerKind::kInverseModel, ControllerKind::kAdaptive}) {
    if (ControllerKindName(k) == name) return k;
  }
  return std::nullopt;
}

Pid::Gains TuneGains(const ParameterSet& params, const KneeTarget& target,
                     const TrackingOptions& options) {
  Require(!target.angle_deg.empty(), "tracking: the target is empty");
  const JointModel joint = JointModel::FromParameters(params);
  double mid = 0.0;
  for (double a : target.angle_deg) mid += a;
  mid /= static_cast<double>(target.size());
  const double gain = joint.ActiveGain(mid, 0.0);
  const double hold = gain > 1e-9 ? std::clamp(-joint.PassiveAngleTorque(mid) / gain, 0.0, 1.0)
                                  : 0.0;
  const auto total = [&](double th) {
    return joint.PassiveAngleTorque(th) + hold * joint.ActiveGain(th, 0.0);
  };
  const double k_theta = std::max(std::abs(total(mid + 1.0) - total(mid - 1.0)) / 2.0, 0.05);
  const double lo = std::max(options.threshold_ma, 0.0);
  const double hi = std::max(options.max_amplitude_ma, lo + 1.0);
  const double slope = std::max((params.irc(hi) - params.irc(lo)) / (hi - lo), 1e-4);
  const double k_u = std::max(gain * slope, 1e-6);
  const double g_deg_per_ma = k_u / k_theta;
  const double loop = options.kind == ControllerKind::kPid ? 0.5 : 0.25;
  Pid::Gains g;
  g.kp_ma_per_deg = loop / g_deg_per_ma;
  g.ki_ma_per_deg_s = g.kp_ma_per_deg / 1.0;
  g.kd_ma_s_per_deg = g.kp_ma_per_deg * 0.1;
  g.derivative_filter_s = 0.02;
  return g;
}

TrackingController::TrackingController(const ParameterSet& params, KneeTarget target,
                                       TrackingOptions options)
    : params_(params),
      joint_(JointModel::FromParameters(params)),
      target_(std::move(target)),
      options_(std::move(options)),
      gains_(options_.gains ? *options_.gains : TuneGains(params, target_, options_)),
      pid_(gains_, 1.0 / (target_.rate_hz > 0.0 ? target_.rate_hz : 1.0), 0.0,
           std::max(options_.max_amplitude_ma, 0.0)),
      dt_s_(1.0 / target_.rate_hz),
      tau_scale_(params.active.torque_scale_nm),
      estimator_(std::max(params.active.torque_scale_nm, 1e-6), options_.forgetting > 0.0 &&
                                                                         options_.forgetting <= 1.0
                                                                     ? options_.forgetting
                                                                     : 1.0),
      chain_(params.contraction) {
  Require(std::isfinite(options_.threshold_ma) && options_.threshold_ma >= 0.0,
          "tracking: threshold_ma must be ≥ 0");
  Require(std::isfinite(options_.max_amplitude_ma) &&
              options_.max_amplitude_ma >= options_.threshold_ma,
          "tracking: max_amplitude_ma must be ≥ threshold_ma");
  Require(std::isfinite(options_.forgetting) && options_.forgetting > 0.0 &&
              options_.forgetting <= 1.0,
          "tracking: forgetting must be in (0, 1]");
  Require(std::isfinite(options_.velocity_filter_hz) && options_.velocity_filter_hz > 0.0 &&
              2.0 * std::numbers::pi * options_.velocity_filter_hz / target_.rate_hz < 1.0,
          "tracking: velocity_filter_hz must be > 0 and well below the sample rate");
  Require(params.active.torque_scale_nm > 0.0, "tracking: the set's τ_scale must be > 0");
  InverseOptions inverse;
  inverse.pulse_rate_hz = options_.pulse_rate_hz;
  inverse.max_amplitude_ma = options_.max_amplitude_ma;
  needed_torque_nm_ = InvertModel(params, target_, inverse).active_torque_nm;
  curve_gain_.resize(target_.size());
  for (std::size_t i = 0; i < target_.size(); ++i) {
    curve_gain_[i] = joint_.ActiveGain(target_.angle_deg[i], target_.velocity_deg_s[i]) /
                     params.active.torque_scale_nm;
  }
  // Step 3 of InvertModel: the recruitment leads by the chain's mean delay n/a.
  lead_ = static_cast<std::size_t>(
      std::lround(params.contraction.order / params.contraction.pole_per_s * target_.rate_hz));
}

double TrackingController::FeedforwardAt(std::size_t i) const {
  if (options_.kind == ControllerKind::kPid) return options_.threshold_ma;
  const std::size_t n = target_.size();
  const std::size_t j = std::min(n - 1, i + lead_);
  const double gain = tau_scale_ * curve_gain_[j];
  const double torque = needed_torque_nm_[j];
  const double f = gain > 1e-9 ? torque / gain : (torque > 0.0 ? 1.0 : 0.0);
  const double u = InverseRecruitment(params_.irc, std::clamp(f, 0.0, 1.0));
  return std::min(u, options_.max_amplitude_ma);
}

void TrackingController::Observe(double measured_deg) {
  const double omega = 2.0 * std::numbers::pi * options_.velocity_filter_hz;
  const double phi_raw =
      chain_.Output(activation_) *
      joint_.ActiveGain(filters_started_ ? angle_filter_[0] : measured_deg,
                        filters_started_ ? angle_filter_[1] : 0.0) /
      params_.active.torque_scale_nm;
  const double passive_raw = joint_.PassiveAngleTorque(measured_deg);
  if (!filters_started_) {
    angle_filter_ = {measured_deg, 0.0};
    passive_filter_ = {passive_raw, 0.0};
    regressor_filter_ = {phi_raw, 0.0};
    filters_started_ = true;
    return;
  }
  const double accel_deg_s2 = FilterStep(angle_filter_, measured_deg, omega, dt_s_);
  FilterStep(passive_filter_, passive_raw, omega, dt_s_);
  FilterStep(regressor_filter_, phi_raw, omega, dt_s_);
  if (options_.kind != ControllerKind::kAdaptive) return;
  if (static_cast<double>(index_) * dt_s_ < kEstimatorWarmupS) return;
  // τ_act = −J·θ̈ − τ_pta(θ) − τ_ptv(θ̇) (Eq. 3.16 solved for the active torque).
  const double active_nm = -joint_.inertia_kgm2() * accel_deg_s2 * kRadPerDeg -
                           passive_filter_[0] - joint_.PassiveVelocityTorque(angle_filter_[1]);
  const double estimate = estimator_.Update(regressor_filter_[0], active_nm);
  const double base = params_.active.torque_scale_nm;
  tau_scale_ = std::clamp(estimate, options_.min_scale_fraction * base,
                          options_.max_scale_fraction * base);
}

TrackingSample TrackingController::Update(double measured_deg) {
  Require(std::isfinite(measured_deg), "tracking: the measured angle is not finite");
  const std::size_t i = std::min(index_, target_.size() - 1);
  Observe(measured_deg);
  TrackingSample s;
  s.target_deg = target_.angle_deg[i];
  s.error_deg = measured_deg - s.target_deg;
  s.feedforward_ma = FeedforwardAt(i);
  s.amplitude_ma = pid_.Update(s.target_deg, measured_deg, s.feedforward_ma);
  s.correction_ma = s.amplitude_ma - s.feedforward_ma;
  s.tau_scale_nm = tau_scale_;
  s.saturated = s.amplitude_ma >= options_.max_amplitude_ma - 1e-9 && s.error_deg > 0.0;
  // The chain of the model, driven by the pulses this amplitude gives until
  // the next sample (the pulse clock runs from the first sample, t = 0).
  const double t = static_cast<double>(index_) * dt_s_;
  const double weight = PulseWeight(params_.irc, s.amplitude_ma, options_.pulse_rate_hz);
  const PulseClock clock(options_.pulse_rate_hz);
  double now = t;
  for (double at = clock.TimeOf(next_pulse_); at < t + dt_s_ - 1e-12;
       at = clock.TimeOf(++next_pulse_)) {
    activation_ = chain_.Propagate(activation_, std::max(0.0, at - now));
    now = std::max(now, at);
    chain_.ApplyImpulse(activation_, weight);
  }
  activation_ = chain_.Propagate(activation_, t + dt_s_ - now);
  ++index_;
  return s;
}

}  // namespace fesbench::model
