#include "model/tracking.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <stdexcept>
#include <string>
#include <unsupported/Eigen/FFT>
#include <utility>

#include "model/evaluation.h"
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
constexpr double kEstimatorWarmupS = 1.0;
// Initial variance of τ̂ per unit regressor²: with λ = 0.999 and φ ≈ 0.3 the
// steady variance is (1 − λ)/φ² ≈ 0.01; starting there, not at a large
// value, keeps the first noisy samples from throwing τ̂ about (a weak
// simulated leg's τ̂ fell to 40 % within 0.1 s and its loop oscillated).
constexpr double kEstimatorVariance = 0.02;

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

double PidRecruitmentSlope(const PiecewiseLinear& irc, double lo, double hi, double activation) {
  Require(std::isfinite(lo) && std::isfinite(hi) && hi > lo && std::isfinite(activation),
          "tracking: the recruitment slope needs finite lo < hi");
  const double a = std::clamp(InverseRecruitment(irc, activation), lo, hi);
  const double c0 = std::max(lo, a - 0.5 * kPidSlopeChordMa);
  const double c1 = std::min(hi, a + 0.5 * kPidSlopeChordMa);
  return c1 > c0 ? (irc(c1) - irc(c0)) / (c1 - c0) : 0.0;
}

LoopShape LoopShapeOf(const ParameterSet& params, const KneeTarget& target,
                      const TrackingOptions& options, std::optional<double> about_deg) {
  Require(!target.angle_deg.empty() && target.rate_hz > 0.0, "tracking: the target is empty");
  const JointModel joint = JointModel::FromParameters(params);
  double mid = 0.0;
  for (double a : target.angle_deg) mid += a;
  mid /= static_cast<double>(target.size());
  if (about_deg) mid = *about_deg;
  const double gain = joint.ActiveGain(mid, 0.0);
  const double hold =
      gain > 1e-9 ? std::clamp(-joint.PassiveAngleTorque(mid) / gain, 0.0, 1.0) : 0.0;
  // Linearised about the hold at θ_m: stiffness and damping of the leg
  // with the holding activation, both per degree.
  const auto angle_torque = [&](double th) {
    return joint.PassiveAngleTorque(th) + hold * joint.ActiveGain(th, 0.0);
  };
  const auto velocity_torque = [&](double w) {
    return joint.PassiveVelocityTorque(w) + hold * joint.ActiveGain(mid, w);
  };
  LoopShape l;
  l.inertia = joint.inertia_kgm2() * kRadPerDeg;
  l.damping = std::max((velocity_torque(1.0) - velocity_torque(-1.0)) / 2.0, 0.0);
  l.stiffness = std::max(std::abs(angle_torque(mid + 1.0) - angle_torque(mid - 1.0)) / 2.0, 0.05);
  l.pole_per_s = params.contraction.pole_per_s;
  l.order = params.contraction.order;
  // A sample of computation, half a sample of hold, half a pulse period.
  l.delay_s = 1.5 / target.rate_hz + 0.5 / options.pulse_rate_hz;
  if (options.kind == ControllerKind::kPid) {
    const double lo = std::max(options.threshold_ma, 0.0);
    const double hi = std::max(options.max_amplitude_ma, lo + 1.0);
    const double slope = std::max(PidRecruitmentSlope(params.irc, lo, hi, hold), 1e-4);
    l.plant_gain = std::max(gain * slope, 1e-6);
    l.integral_s = 1.0;
    l.derivative_s = 0.1;
  } else {
    l.plant_gain = 1.0;
    l.integral_s = 0.5;
    l.derivative_s = 0.03;
  }
  return l;
}

std::complex<double> UnitLoop(const LoopShape& l, double omega) {
  const std::complex<double> s(0.0, omega);
  const std::complex<double> contraction = std::pow(l.pole_per_s / (s + l.pole_per_s), l.order);
  const std::complex<double> leg = 1.0 / (l.inertia * s * s + l.damping * s + l.stiffness);
  const std::complex<double> pid =
      1.0 + 1.0 / (l.integral_s * s) + l.derivative_s * s / (1.0 + l.derivative_filter_s * s);
  return l.plant_gain * contraction * leg * pid * std::exp(-s * l.delay_s);
}

std::optional<double> PhaseCrossover(const LoopShape& l) {
  // Log-spaced sweep 0.05–500 rad/s, the phase unwrapped from the lowest
  // frequency (where the integral holds it near −90°).
  constexpr int kPoints = 4000;
  const double lo = std::log(0.05), hi = std::log(500.0);
  double previous_omega = std::exp(lo);
  std::complex<double> previous = UnitLoop(l, previous_omega);
  double phase = std::arg(previous);
  for (int k = 1; k <= kPoints; ++k) {
    const double omega = std::exp(lo + (hi - lo) * k / kPoints);
    const std::complex<double> value = UnitLoop(l, omega);
    const double next = phase + std::arg(value / previous);
    if (next <= -std::numbers::pi) {
      const double x = (phase + std::numbers::pi) / (phase - next);  // in (0, 1]
      return std::exp(std::log(previous_omega) + x * (std::log(omega) - std::log(previous_omega)));
    }
    phase = next;
    previous = value;
    previous_omega = omega;
  }
  return std::nullopt;
}

Pid::Gains TuneGains(const ParameterSet& params, const KneeTarget& target,
                     const TrackingOptions& options) {
  const LoopShape l = LoopShapeOf(params, target, options);
  // The cap: a static loop gain kp·plant_gain/K_θ of 1 (amplitude) or 2
  // (torque: the loop at most triples the leg's stiffness).
  const double cap =
      (options.kind == ControllerKind::kPid ? 1.0 : 2.0) * l.stiffness / l.plant_gain;
  double kp = cap;
  const auto [lo, hi] = std::minmax_element(target.angle_deg.begin(), target.angle_deg.end());
  for (std::optional<double> about :
       {std::optional<double>(), std::optional<double>(*lo), std::optional<double>(*hi)}) {
    const LoopShape at = LoopShapeOf(params, target, options, about);
    if (const std::optional<double> w = PhaseCrossover(at)) {
      kp = std::min(kp, 1.0 / (kGainMargin * std::abs(UnitLoop(at, *w))));
    }
  }
  Pid::Gains g;
  g.kp = kp;
  g.ki = kp / l.integral_s;
  g.kd = kp * l.derivative_s;
  g.derivative_filter_s = l.derivative_filter_s;
  return g;
}

double SlewLimitFor(const LoopShape& l, double span_ma) {
  Require(std::isfinite(span_ma) && span_ma >= 0.0, "slew limit: the span must be ≥ 0 mA");
  const std::optional<double> w = PhaseCrossover(l);
  const double omega = w ? *w : 1.0 / std::max(l.delay_s, 1e-3);
  return std::clamp(omega * span_ma / 2.0, kMinSlewLimitMaPerS, kMaxSlewLimitMaPerS);
}

double DefaultSlewLimit(const ParameterSet& params, const KneeTarget& target,
                        const TrackingOptions& options) {
  const double span = std::max(options.max_amplitude_ma - std::max(options.threshold_ma, 0.0), 0.0);
  return SlewLimitFor(LoopShapeOf(params, target, options), span);
}

double ReachableExtensionDeg(const ParameterSet& params, double max_amplitude_ma,
                             double activation_fraction) {
  Require(std::isfinite(max_amplitude_ma) && max_amplitude_ma >= 0.0,
          "reachable angle: the amplitude must be ≥ 0");
  Require(
      std::isfinite(activation_fraction) && activation_fraction > 0.0 && activation_fraction <= 1.0,
      "reachable angle: the activation fraction must be in (0, 1]");
  const JointModel joint = JointModel::FromParameters(params);
  const double available = activation_fraction * std::clamp(params.irc(max_amplitude_ma), 0.0, 1.0);
  std::optional<double> rest;
  if (!params.passive.torque_angle.empty() && !params.passive.torque_velocity.empty()) {
    rest = FindPassiveRestAngle(params.passive);
  }
  // Tenths of a degree, from the rest angle toward extension.
  const auto start = static_cast<int>(std::floor(rest.value_or(kReferenceAngleDeg) * 10.0));
  int reached = std::max(start, 0);
  for (int k = reached; k >= 0; --k) {
    const double angle = 0.1 * k;
    const double need = -joint.PassiveAngleTorque(angle);  // extension torque to hold
    if (need > 0.0 && need > available * joint.ActiveGain(angle, 0.0)) break;
    reached = k;
  }
  return 0.1 * reached;
}

std::vector<double> ResampleTarget(const std::vector<double>& t_s,
                                   const std::vector<double>& angle_deg, double rate_hz) {
  Require(std::isfinite(rate_hz) && rate_hz > 0.0, "target: the rate must be > 0");
  Require(t_s.size() == angle_deg.size(), "target: t_s and angle_deg differ in length");
  Require(t_s.size() >= 3, "target: at least 3 samples");
  for (std::size_t i = 0; i < t_s.size(); ++i) {
    Require(std::isfinite(t_s[i]) && std::isfinite(angle_deg[i]),
            "target: sample " + std::to_string(i) + " is not finite");
    Require(i == 0 || t_s[i] > t_s[i - 1],
            "target: t_s must increase strictly (sample " + std::to_string(i) + ")");
  }
  const double duration = t_s.back() - t_s.front();
  const auto n = static_cast<std::size_t>(std::floor(duration * rate_hz + 1e-9)) + 1;
  std::vector<double> out(n);
  std::size_t j = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = t_s.front() + static_cast<double>(i) / rate_hz;
    while (j + 2 < t_s.size() && t_s[j + 1] < t) ++j;
    const double x = std::clamp((t - t_s[j]) / (t_s[j + 1] - t_s[j]), 0.0, 1.0);
    out[i] = angle_deg[j] + x * (angle_deg[j + 1] - angle_deg[j]);
  }
  return out;
}

KneeTarget WithLeadIn(const KneeTarget& target, double from_deg, double lead_in_s) {
  Require(!target.angle_deg.empty() && target.rate_hz > 0.0, "lead-in: the target is empty");
  Require(std::isfinite(from_deg) && std::isfinite(lead_in_s) && lead_in_s >= 0.0,
          "lead-in: need a finite start angle and a lead-in ≥ 0 s");
  KneeTarget out;
  out.rate_hz = target.rate_hz;
  const auto n = static_cast<std::size_t>(std::llround(lead_in_s * target.rate_hz));
  const double d = target.angle_deg.front() - from_deg;
  const double p = n > 0 ? std::numbers::pi / lead_in_s : 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / target.rate_hz;
    out.angle_deg.push_back(from_deg + 0.5 * d * (1.0 - std::cos(p * t)));
    out.velocity_deg_s.push_back(0.5 * d * p * std::sin(p * t));
    out.accel_deg_s2.push_back(0.5 * d * p * p * std::cos(p * t));
  }
  out.angle_deg.insert(out.angle_deg.end(), target.angle_deg.begin(), target.angle_deg.end());
  out.velocity_deg_s.insert(out.velocity_deg_s.end(), target.velocity_deg_s.begin(),
                            target.velocity_deg_s.end());
  out.accel_deg_s2.insert(out.accel_deg_s2.end(), target.accel_deg_s2.begin(),
                          target.accel_deg_s2.end());
  return out;
}

TrackingMetrics MeasureTracking(const KneeTarget& target, const std::vector<double>& angle_deg,
                                double settle_band_deg) {
  const std::size_t n = std::min(target.size(), angle_deg.size());
  Require(n > 0, "tracking metrics: no samples");
  Require(std::isfinite(settle_band_deg) && settle_band_deg > 0.0,
          "tracking metrics: the settle band must be > 0");
  TrackingMetrics m;
  double sum = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double e = angle_deg[i] - target.angle_deg[i];
    sum += e * e;
    m.max_error_deg = std::max(m.max_error_deg, std::abs(e));
  }
  m.rms_deg = std::sqrt(sum / static_cast<double>(n));
  // Holds: a plateau (zero target velocity) that follows a move.
  std::vector<double> overshoots, settlings;
  for (std::size_t i = 1; i < n; ++i) {
    if (!(target.velocity_deg_s[i] == 0.0 && target.velocity_deg_s[i - 1] != 0.0)) continue;
    std::size_t j = i;
    while (j < n && target.velocity_deg_s[j] == 0.0) ++j;
    // The move's direction: + toward flexion.
    std::size_t k = i;
    while (k > 0 && target.velocity_deg_s[k - 1] != 0.0) --k;
    const double direction = target.angle_deg[i] > target.angle_deg[k] ? 1.0 : -1.0;
    double overshoot = 0.0;
    std::size_t last_out = i;  // last sample outside the band
    bool any_out = false;
    for (std::size_t q = i; q < j; ++q) {
      const double e = angle_deg[q] - target.angle_deg[q];
      overshoot = std::max(overshoot, direction * e);
      if (std::abs(e) > settle_band_deg) {
        last_out = q;
        any_out = true;
      }
    }
    overshoots.push_back(overshoot);
    settlings.push_back(any_out ? static_cast<double>(last_out + 1 - i) / target.rate_hz : 0.0);
    i = j;
  }
  const auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const std::size_t h = v.size() / 2;
    return v.size() % 2 ? v[h] : 0.5 * (v[h - 1] + v[h]);
  };
  if (!overshoots.empty()) {
    m.overshoot_deg = median(overshoots);
    m.settling_s = median(settlings);
    m.worst_overshoot_deg = *std::max_element(overshoots.begin(), overshoots.end());
    m.worst_settling_s = *std::max_element(settlings.begin(), settlings.end());
  }
  // The error above 1 Hz: Parseval, Σ_n e² = (1/N)·Σ_k |E_k|², over the
  // bins whose frequency k·rate/N (or (N − k)·rate/N) exceeds 1 Hz.
  if (static_cast<double>(n) >= 2.0 * target.rate_hz) {
    std::vector<double> e(n);
    for (std::size_t i = 0; i < n; ++i) e[i] = angle_deg[i] - target.angle_deg[i];
    std::vector<std::complex<double>> spectrum;
    Eigen::FFT<double> fft;
    fft.fwd(spectrum, e);
    double high = 0.0;
    for (std::size_t k = 1; k < n; ++k) {
      const double f_hz =
          static_cast<double>(std::min(k, n - k)) * target.rate_hz / static_cast<double>(n);
      if (f_hz > 1.0) high += std::norm(spectrum[k]);
    }
    m.rms_above_1hz_deg = std::sqrt(high / static_cast<double>(n) / static_cast<double>(n));
  }
  return m;
}

OscillationDetector::OscillationDetector(double rate_hz, Options options)
    : options_(options), dt_s_(rate_hz > 0.0 ? 1.0 / rate_hz : 1.0) {
  Require(std::isfinite(rate_hz) && rate_hz > 0.0, "oscillation detector: rate must be > 0");
  Require(std::isfinite(options.peak_deg) && std::isfinite(options.max_half_period_s) &&
              std::isfinite(options.hysteresis_deg) && options.hysteresis_deg > 0.0 &&
              options.peak_deg > options.hysteresis_deg && options.max_half_period_s > 0.0 &&
              options.half_cycles >= 2 && std::isfinite(options.sustain) &&
              options.sustain >= 0.0 && options.sustain <= 1.0,
          "oscillation detector: need 0 < hysteresis < peak, a half-period > 0, at least "
          "2 half-cycles and a sustain ratio in [0, 1]");
}

bool OscillationDetector::Update(double error_deg) {
  length_s_ += dt_s_;
  const int sign = error_deg > options_.hysteresis_deg    ? 1
                   : error_deg < -options_.hysteresis_deg ? -1
                                                          : sign_;
  if (sign != sign_) {
    // A half-cycle ended (the first sign change only starts the count).
    if (sign_ != 0) {
      const bool swing = peak_deg_ >= options_.peak_deg &&
                         length_s_ - dt_s_ <= options_.max_half_period_s &&
                         peak_deg_ >= options_.sustain * before_previous_peak_deg_;
      count_ = swing ? count_ + 1 : 0;
      before_previous_peak_deg_ = previous_peak_deg_;
      previous_peak_deg_ = peak_deg_;
    }
    sign_ = sign;
    peak_deg_ = 0.0;
    length_s_ = dt_s_;
  }
  peak_deg_ = std::max(peak_deg_, std::abs(error_deg));
  // A half-cycle that has outlasted the period breaks the run of swings.
  if (length_s_ > options_.max_half_period_s) count_ = 0;
  if (count_ < options_.half_cycles) return false;
  // What follows (a back-off) is judged on its own swings.
  count_ = 0;
  previous_peak_deg_ = before_previous_peak_deg_ = 0.0;
  return true;
}

void BackOffOnOscillation(OscillationDetector& detector, Pid& pid, int& backoffs,
                          TrackingSample& sample) {
  // A limit cycle: the loop has more gain than its delay allows here.
  if (!detector.Update(sample.error_deg)) return;
  if (backoffs < kMaxOscillationBackoffs) {
    pid.ScaleGains(0.5);
    ++backoffs;
    sample.backed_off = true;
  } else {
    sample.oscillating = true;
  }
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
      base_scale_(params.active.torque_scale_nm),
      estimator_(
          std::max(params.active.torque_scale_nm, 1e-6),
          options_.forgetting > 0.0 && options_.forgetting <= 1.0 ? options_.forgetting : 1.0,
          kEstimatorVariance),
      chain_(params.contraction),
      oscillation_(target_.rate_hz > 0.0 ? target_.rate_hz : 1.0, {}) {
  Require(std::isfinite(options_.threshold_ma) && options_.threshold_ma >= 0.0,
          "tracking: threshold_ma must be ≥ 0");
  Require(std::isfinite(options_.max_amplitude_ma) &&
              options_.max_amplitude_ma >= options_.threshold_ma,
          "tracking: max_amplitude_ma must be ≥ threshold_ma");
  Require(
      std::isfinite(options_.forgetting) && options_.forgetting > 0.0 && options_.forgetting <= 1.0,
      "tracking: forgetting must be in (0, 1]");
  Require(std::isfinite(options_.velocity_filter_hz) && options_.velocity_filter_hz > 0.0 &&
              2.0 * std::numbers::pi * options_.velocity_filter_hz / target_.rate_hz < 1.0,
          "tracking: velocity_filter_hz must be > 0 and well below the sample rate");
  Require(params.active.torque_scale_nm > 0.0, "tracking: the set's τ_scale must be > 0");
  if (options_.kind == ControllerKind::kAdaptive && options_.strength) {
    strength_model_.emplace(*options_.strength);
  }
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

double TrackingController::FeedforwardActivation(std::size_t i) const {
  const std::size_t j = std::min(target_.size() - 1, i + lead_);
  const double gain = tau_scale_ * curve_gain_[j];
  const double torque = needed_torque_nm_[j];
  const double f = gain > 1e-9 ? torque / gain : (torque > 0.0 ? 1.0 : 0.0);
  return std::clamp(f, 0.0, 1.0);
}

double TrackingController::AmplitudeFor(double activation) const {
  return std::min(InverseRecruitment(params_.irc, activation), options_.max_amplitude_ma);
}

void TrackingController::Observe(double measured_deg) {
  const double omega = 2.0 * std::numbers::pi * options_.velocity_filter_hz;
  // φ with the strength the stimulation history predicts: the regression
  // τ_act = (g·τ_scale)·(s·φ) estimates g·τ_scale (s ≡ 1 without a state).
  const double phi_raw = StrengthFactor(strength_) * chain_.Output(activation_) *
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
  const double active_nm = -joint_.inertia_kgm2() * accel_deg_s2 * kRadPerDeg - passive_filter_[0] -
                           joint_.PassiveVelocityTorque(angle_filter_[1]);
  const double estimate = estimator_.Update(regressor_filter_[0], active_nm);
  const double base = params_.active.torque_scale_nm;
  base_scale_ =
      std::clamp(estimate, options_.min_scale_fraction * base, options_.max_scale_fraction * base);
}

TrackingSample TrackingController::Update(double measured_deg) {
  Require(std::isfinite(measured_deg), "tracking: the measured angle is not finite");
  const std::size_t i = std::min(index_, target_.size() - 1);
  Observe(measured_deg);
  if (options_.kind == ControllerKind::kAdaptive) {
    const double base = params_.active.torque_scale_nm;
    tau_scale_ = std::clamp(base_scale_ * StrengthFactor(strength_),
                            options_.min_scale_fraction * base, options_.max_scale_fraction * base);
  }
  TrackingSample s;
  s.target_deg = target_.angle_deg[i];
  s.error_deg = measured_deg - s.target_deg;
  bool top_activation = false;
  if (options_.kind == ControllerKind::kPid) {
    // The clinic's PID: the threshold plus a correction in mA.
    s.feedforward_ma = options_.threshold_ma;
    s.amplitude_ma = pid_.Update(s.target_deg, measured_deg, s.feedforward_ma);
  } else {
    // The PID around the compensator (§7.6.3) corrects the torque; the
    // inverse turns the corrected torque into activation and amplitude, so
    // the loop sees a linear plant whatever the recruitment's shape. Its
    // output is held to what the muscle can add or remove now.
    const double f_ff = FeedforwardActivation(i);
    // The correction goes through the set's τ_scale, not τ̂: a leg found
    // weaker than its set then sees a smaller loop gain (the safe side of
    // the margin), while the feedforward follows τ̂.
    const double gain = params_.active.torque_scale_nm * curve_gain_[i];
    const double f_max = std::clamp(params_.irc(options_.max_amplitude_ma), 0.0, 1.0);
    if (gain > 1e-9) {
      pid_.SetLimits(-f_ff * gain, std::max(0.0, f_max - f_ff) * gain);
    } else {
      pid_.SetLimits(0.0, 0.0);
    }
    const double correction_nm = pid_.Update(s.target_deg, measured_deg);
    const double f = gain > 1e-9 ? f_ff + correction_nm / gain : f_ff;
    s.feedforward_ma = AmplitudeFor(f_ff);
    s.amplitude_ma = AmplitudeFor(std::clamp(f, 0.0, 1.0));
    // Asking for the whole muscle is saturation too, below the maximum.
    top_activation = f >= f_max - 1e-9;
  }
  s.correction_ma = s.amplitude_ma - s.feedforward_ma;
  s.tau_scale_nm = tau_scale_;
  BackOffOnOscillation(oscillation_, pid_, backoffs_, s);
  // The PID wanting more than its limit counts too: its integral is held
  // just below the limit, so the output may sit a hair under it.
  s.saturated = (s.amplitude_ma >= options_.max_amplitude_ma - 1e-9 || top_activation ||
                 pid_.saturated_high()) &&
                s.error_deg > 0.0;
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
  // The strength state, driven by the activation this amplitude's train
  // asks for (R(u): its mean f_stim), constant until the next sample.
  if (strength_model_) {
    const double f = s.amplitude_ma > 0.0 ? params_.irc(s.amplitude_ma) : 0.0;
    strength_ = strength_model_->Propagate(strength_, f, dt_s_);
  }
  ++index_;
  return s;
}

}  // namespace fesbench::model
