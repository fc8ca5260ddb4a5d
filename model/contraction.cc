#include "model/contraction.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace fesbench::model {

void ValidateContraction(const ContractionParams& contraction) {
  if (contraction.order != 2 && contraction.order != 3) {
    throw std::invalid_argument("contraction.order must be 2 or 3, got " +
                                std::to_string(contraction.order));
  }
  if (!std::isfinite(contraction.pole_per_s) || !(contraction.pole_per_s > 0.0)) {
    throw std::invalid_argument("contraction.pole_per_s must be finite and > 0");
  }
}

double ImpulseResponse(const ContractionParams& contraction, double t_s) {
  ValidateContraction(contraction);
  if (t_s < 0.0) return 0.0;
  const double a = contraction.pole_per_s;
  const int n = contraction.order;
  // Eqs. 3.21, 4.1, 4.3 scaled to unit area: aⁿ·t^(n−1)·e^(−a·t)/(n−1)!.
  double factorial = 1.0;
  for (int k = 2; k < n; ++k) factorial *= k;
  return std::pow(a, n) * std::pow(t_s, n - 1) * std::exp(-a * t_s) / factorial;
}

double ImpulseResponsePeakTime(const ContractionParams& contraction) {
  ValidateContraction(contraction);
  return (contraction.order - 1) / contraction.pole_per_s;  // Eqs. 4.2, 4.4
}

ContractionStateSpace MakeContractionStateSpace(const ContractionParams& contraction) {
  ValidateContraction(contraction);
  const int n = contraction.order;
  const double a = contraction.pole_per_s;
  ContractionStateSpace ss;
  ss.a = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i < n; ++i) {
    ss.a(i, i) = -a;
    if (i > 0) ss.a(i, i - 1) = a;
  }
  ss.b = Eigen::VectorXd::Zero(n);
  ss.b(0) = a;
  ss.c = Eigen::RowVectorXd::Zero(n);
  ss.c(n - 1) = 1.0;
  return ss;
}

ContractionPropagator::ContractionPropagator(const ContractionParams& contraction)
    : order_((ValidateContraction(contraction), contraction.order)),
      pole_per_s_(contraction.pole_per_s) {}

const ContractionPropagator::Factors& ContractionPropagator::FactorsFor(double dt_s) {
  static const Factors kIdentity{0.0, {1.0, 0.0, 0.0}};
  if (dt_s == 0.0) return kIdentity;
  // Steps computed as differences of sample times differ in the last bits;
  // reusing factors within 1e-12 relative changes the result by ~1e-12·a·dt.
  for (const Factors& f : cache_) {
    if (std::abs(f.dt_s - dt_s) <= 1e-12 * dt_s) return f;
  }
  Factors& f = cache_[next_slot_];
  next_slot_ = 1 - next_slot_;
  const double adt = pole_per_s_ * dt_s;
  const double decay = std::exp(-adt);
  f.dt_s = dt_s;
  f.coeff[0] = decay;
  f.coeff[1] = decay * adt;
  f.coeff[2] = decay * adt * adt / 2.0;
  return f;
}

double ContractionPropagator::OutputAfter(const ContractionState& x, double dt_s) {
  return OutputAfter(x, StepFor(dt_s));
}

double PulseWeight(const PiecewiseLinear& irc, double stim_ma, double pulse_rate_hz) {
  return std::max(0.0, irc(stim_ma)) / pulse_rate_hz;
}

void ValidatePulseTrain(const PulseTrain& pulses) {
  for (std::size_t k = 0; k < pulses.size(); ++k) {
    const Pulse& p = pulses[k];
    if (!std::isfinite(p.t_s) || !std::isfinite(p.stim_ma)) {
      throw std::invalid_argument("pulse train: non-finite time or amplitude at pulse " +
                                  std::to_string(k));
    }
    if (p.t_s < 0.0) {
      throw std::invalid_argument("pulse train: negative time at pulse " + std::to_string(k));
    }
    if (p.stim_ma < 0.0) {
      throw std::invalid_argument("pulse train: negative stim_ma at pulse " + std::to_string(k));
    }
    if (k > 0 && !(p.t_s > pulses[k - 1].t_s)) {
      throw std::invalid_argument("pulse train: pulse times not strictly increasing at pulse " +
                                  std::to_string(k));
    }
  }
}

std::vector<double> ActivationAt(const ContractionParams& contraction, const PiecewiseLinear& irc,
                                 const PulseTrain& pulses, double pulse_rate_hz,
                                 std::span<const double> t_s) {
  ValidateContraction(contraction);
  if (irc.empty()) throw std::invalid_argument("ActivationAt: irc is empty");
  if (!std::isfinite(pulse_rate_hz) || !(pulse_rate_hz > 0.0)) {
    throw std::invalid_argument("ActivationAt: pulse_rate_hz must be finite and > 0");
  }
  ValidatePulseTrain(pulses);
  for (std::size_t i = 0; i < t_s.size(); ++i) {
    if (!std::isfinite(t_s[i]) || (i > 0 && t_s[i] < t_s[i - 1])) {
      throw std::invalid_argument(
          "ActivationAt: sample times must be finite and non-decreasing (index " +
          std::to_string(i) + ")");
    }
  }
  ContractionPropagator prop(contraction);
  ContractionState x{};
  double t_state = 0.0;
  std::size_t next_pulse = 0;
  std::vector<double> out(t_s.size(), 0.0);
  for (std::size_t i = 0; i < t_s.size(); ++i) {
    const double t = t_s[i];
    while (next_pulse < pulses.size() && pulses[next_pulse].t_s <= t) {
      const Pulse& p = pulses[next_pulse++];
      x = prop.Propagate(x, p.t_s - t_state);
      t_state = p.t_s;
      prop.ApplyImpulse(x, PulseWeight(irc, p.stim_ma, pulse_rate_hz));
    }
    // Before t = 0 the muscle is at rest.
    out[i] = t < t_state ? 0.0 : prop.OutputAfter(x, t - t_state);
  }
  return out;
}

}  // namespace fesbench::model
