#include "model/inverse_model.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "model/joint_model.h"
#include "model/units.h"

namespace fesbench::model {
namespace {

void Require(bool ok, const std::string& message) {
  if (!ok) throw std::invalid_argument(message);
}

bool Finite(std::initializer_list<double> values) {
  return std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); });
}

std::size_t Samples(double duration_s, double rate_hz) {
  return static_cast<std::size_t>(std::floor(duration_s * rate_hz + 1e-9)) + 1;
}

}  // namespace

double KneeTarget::duration_s() const {
  return angle_deg.empty() ? 0.0 : static_cast<double>(angle_deg.size() - 1) / rate_hz;
}

KneeTarget SineTarget(double lo_deg, double hi_deg, double frequency_hz, double duration_s,
                      double rate_hz) {
  Require(Finite({lo_deg, hi_deg, frequency_hz, duration_s, rate_hz}) && lo_deg < hi_deg &&
              frequency_hz > 0.0 && duration_s > 0.0 && rate_hz > 0.0,
          "sine target: need lo < hi, frequency > 0, duration > 0, rate > 0");
  KneeTarget target;
  target.rate_hz = rate_hz;
  const double mid = 0.5 * (lo_deg + hi_deg), amp = 0.5 * (hi_deg - lo_deg);
  const double w = 2.0 * std::numbers::pi * frequency_hz;
  for (std::size_t i = 0, n = Samples(duration_s, rate_hz); i < n; ++i) {
    const double t = static_cast<double>(i) / rate_hz;
    target.angle_deg.push_back(mid + amp * std::sin(w * t));
    target.velocity_deg_s.push_back(amp * w * std::cos(w * t));
    target.accel_deg_s2.push_back(-amp * w * w * std::sin(w * t));
  }
  return target;
}

KneeTarget HoldsTarget(const std::vector<double>& angles_deg, double hold_s, double move_s,
                       double rate_hz) {
  Require(!angles_deg.empty() && Finite({hold_s, move_s, rate_hz}) && hold_s >= 0.0 &&
              move_s > 0.0 && rate_hz > 0.0,
          "holds target: need angles, hold ≥ 0 s, move > 0 s, rate > 0");
  for (double a : angles_deg) Require(std::isfinite(a), "holds target: angles must be finite");
  KneeTarget target;
  target.rate_hz = rate_hz;
  const double segment = hold_s + move_s;
  const double duration = hold_s + static_cast<double>(angles_deg.size() - 1) * segment;
  for (std::size_t i = 0, n = Samples(duration, rate_hz); i < n; ++i) {
    const double t = static_cast<double>(i) / rate_hz;
    // Segment k: hold at angle k for hold_s, then move to angle k + 1.
    const std::size_t k = std::min(static_cast<std::size_t>(t / segment), angles_deg.size() - 1);
    const double tau = t - static_cast<double>(k) * segment - hold_s;
    double angle = angles_deg[k], velocity = 0.0, accel = 0.0;
    if (k + 1 < angles_deg.size() && tau > 0.0) {
      // Raised cosine: θ = a + (b − a)·(1 − cos(π·τ/T))/2.
      const double d = angles_deg[k + 1] - angles_deg[k], p = std::numbers::pi / move_s;
      const double s = std::min(tau, move_s);
      angle += 0.5 * d * (1.0 - std::cos(p * s));
      if (tau < move_s) {
        velocity = 0.5 * d * p * std::sin(p * s);
        accel = 0.5 * d * p * p * std::cos(p * s);
      }
    }
    target.angle_deg.push_back(angle);
    target.velocity_deg_s.push_back(velocity);
    target.accel_deg_s2.push_back(accel);
  }
  return target;
}

KneeTarget SampledTarget(std::vector<double> angle_deg, double rate_hz) {
  Require(angle_deg.size() >= 3, "sampled target: at least 3 samples");
  Require(std::isfinite(rate_hz) && rate_hz > 0.0, "sampled target: rate must be > 0");
  for (double a : angle_deg) Require(std::isfinite(a), "sampled target: angles must be finite");
  KneeTarget target;
  target.rate_hz = rate_hz;
  const std::size_t n = angle_deg.size();
  auto d = [&](const std::vector<double>& x, std::size_t i) {
    if (i == 0) return (x[1] - x[0]) * rate_hz;
    if (i + 1 == n) return (x[n - 1] - x[n - 2]) * rate_hz;
    return 0.5 * (x[i + 1] - x[i - 1]) * rate_hz;
  };
  for (std::size_t i = 0; i < n; ++i) target.velocity_deg_s.push_back(d(angle_deg, i));
  for (std::size_t i = 0; i < n; ++i) target.accel_deg_s2.push_back(d(target.velocity_deg_s, i));
  target.angle_deg = std::move(angle_deg);
  return target;
}

double InverseRecruitment(const PiecewiseLinear& irc, double activation) {
  Require(!irc.empty(), "inverse recruitment: the recruitment curve is empty");
  if (!(activation > 0.0)) return 0.0;
  const std::vector<double>& x = irc.x();
  const std::vector<double>& y = irc.y();
  for (std::size_t i = 0; i + 1 < x.size(); ++i) {
    if (y[i] < activation && activation <= y[i + 1]) {
      return x[i] + (activation - y[i]) / (y[i + 1] - y[i]) * (x[i + 1] - x[i]);
    }
  }
  // At or above the top: where the top is first reached.
  const std::size_t top =
      static_cast<std::size_t>(std::max_element(y.begin(), y.end()) - y.begin());
  return activation <= y.front() ? x.front() : x[top];
}

Feedforward InvertModel(const ParameterSet& params, const KneeTarget& target,
                        const InverseOptions& options) {
  Require(target.size() >= 2 && target.velocity_deg_s.size() == target.size() &&
              target.accel_deg_s2.size() == target.size() && target.rate_hz > 0.0,
          "inverse model: the target needs ≥ 2 samples of angle, velocity and acceleration");
  Require(std::isfinite(options.pulse_rate_hz) && options.pulse_rate_hz > 0.0,
          "inverse model: pulse_rate_hz must be > 0");
  Require(std::isfinite(options.max_amplitude_ma) && options.max_amplitude_ma >= 0.0,
          "inverse model: max_amplitude_ma must be ≥ 0");
  const JointModel joint = JointModel::FromParameters(params);
  const std::size_t n = target.size();
  Feedforward out;
  out.activation.resize(n);
  out.saturated.assign(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / target.rate_hz;
    const double th = target.angle_deg[i], w = target.velocity_deg_s[i];
    // Steps 1–2: the torque and the activation the trajectory needs.
    const double torque = -joint.inertia_kgm2() * target.accel_deg_s2[i] * kRadPerDeg -
                          joint.PassiveAngleTorque(th) - joint.PassiveVelocityTorque(w);
    const double gain = joint.ActiveGain(th, w);
    double f = gain > 1e-9 ? torque / gain : (torque > 0.0 ? 2.0 : 0.0);
    if (f < 0.0 || f > 1.0) {
      out.saturated[i] = 1;
      f = std::clamp(f, 0.0, 1.0);
    }
    out.t_s.push_back(t);
    out.active_torque_nm.push_back(torque);
    out.activation[i] = f;
  }
  // Step 3: the recruitment leads the activation by the chain's mean delay.
  const double lead_s = options.compensate_contraction
                            ? params.contraction.order / params.contraction.pole_per_s
                            : 0.0;
  const auto lead = static_cast<std::ptrdiff_t>(std::lround(lead_s * target.rate_hz));
  out.amplitude_ma.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t j = std::min(n - 1, i + static_cast<std::size_t>(lead));
    // Step 4: the amplitude, capped.
    double u = InverseRecruitment(params.irc, out.activation[j]);
    if (u > options.max_amplitude_ma) {
      u = options.max_amplitude_ma;
      out.saturated[i] = 1;
    }
    out.amplitude_ma[i] = u;
  }
  // Step 5: the pulse clock.
  const PulseClock clock(options.pulse_rate_hz);
  const double end = out.t_s.back();
  for (std::int64_t k = 0; clock.TimeOf(k) <= end + 1e-12; ++k) {
    const double t = clock.TimeOf(k);
    const double x = t * target.rate_hz;
    const auto i = std::min(n - 2, static_cast<std::size_t>(x));
    const double frac = std::clamp(x - static_cast<double>(i), 0.0, 1.0);
    const double u = out.amplitude_ma[i] + frac * (out.amplitude_ma[i + 1] - out.amplitude_ma[i]);
    out.pulses.push_back({t, u});
  }
  return out;
}

Pid::Pid(Gains gains, double dt_s, double min_out, double max_out)
    : gains_(gains), dt_s_(dt_s), min_out_(min_out), max_out_(max_out) {
  Require(Finite({gains.kp, gains.ki, gains.kd, gains.derivative_filter_s}) && gains.kp >= 0.0 &&
              gains.ki >= 0.0 && gains.kd >= 0.0 && gains.derivative_filter_s >= 0.0,
          "pid: gains and filter time must be finite and ≥ 0");
  Require(std::isfinite(dt_s) && dt_s > 0.0, "pid: dt must be > 0");
  Require(Finite({min_out, max_out}) && min_out <= max_out, "pid: need min_out ≤ max_out");
}

void Pid::Reset() {
  integral_ = derivative_ = 0.0;
  first_ = true;
  saturated_ = saturated_high_ = false;
}

void Pid::ScaleGains(double k) {
  Require(std::isfinite(k) && k > 0.0 && k <= 1.0, "pid: a gain factor must be in (0, 1]");
  gains_.kp *= k;
  gains_.ki *= k;
  gains_.kd *= k;
  integral_ /= k;
}

void Pid::SetLimits(double min_out, double max_out) {
  Require(Finite({min_out, max_out}) && min_out <= max_out, "pid: need min_out ≤ max_out");
  min_out_ = min_out;
  max_out_ = max_out;
}

double Pid::Update(double target_deg, double measured_deg, double feedforward) {
  // Flexion error: positive when the knee is more flexed than asked, which
  // more (extensor) stimulation corrects.
  const double error = measured_deg - target_deg;
  double rate = 0.0;
  if (!first_) rate = (measured_deg - last_measured_) / dt_s_;
  const double alpha =
      gains_.derivative_filter_s > 0.0 ? dt_s_ / (gains_.derivative_filter_s + dt_s_) : 1.0;
  derivative_ = first_ ? 0.0 : derivative_ + alpha * (rate - derivative_);
  first_ = false;
  last_measured_ = measured_deg;
  const double candidate_integral = integral_ + error * dt_s_;
  auto output = [&](double integral) {
    return feedforward + gains_.kp * error + gains_.ki * integral + gains_.kd * derivative_;
  };
  const double unclamped = output(candidate_integral);
  saturated_ = unclamped > max_out_ || unclamped < min_out_;
  saturated_high_ = unclamped > max_out_;
  // Anti-windup: the integral only moves while the output is free, or when
  // it moves the output back inside.
  if (!saturated_ || (unclamped > max_out_ && error < 0.0) ||
      (unclamped < min_out_ && error > 0.0)) {
    integral_ = candidate_integral;
  }
  return std::clamp(output(integral_), min_out_, max_out_);
}

ScaleEstimator::ScaleEstimator(double initial_nm, double forgetting, double initial_variance,
                               double min_regressor)
    : estimate_(initial_nm),
      forgetting_(forgetting),
      variance_(initial_variance),
      min_regressor_(min_regressor) {
  Require(Finite({initial_nm, forgetting, initial_variance, min_regressor}) && initial_nm > 0.0 &&
              forgetting > 0.0 && forgetting <= 1.0 && initial_variance > 0.0 &&
              min_regressor >= 0.0,
          "scale estimator: need τ_scale > 0, 0 < λ ≤ 1, variance > 0");
}

double ScaleEstimator::Update(double regressor, double active_torque_nm) {
  if (!std::isfinite(regressor) || !std::isfinite(active_torque_nm) ||
      std::abs(regressor) < min_regressor_) {
    return estimate_;
  }
  // Scalar RLS: gain k = Pφ/(λ + φPφ), θ += k(y − φθ), P = (P − kφP)/λ.
  const double k = variance_ * regressor / (forgetting_ + regressor * variance_ * regressor);
  estimate_ += k * (active_torque_nm - regressor * estimate_);
  variance_ = (variance_ - k * regressor * variance_) / forgetting_;
  estimate_ = std::max(estimate_, 0.0);
  return estimate_;
}

}  // namespace fesbench::model
