#include "model/strength.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace fesbench::model {
namespace {

// dy/dt = a − b·y over dt at constant a, b > 0: y_∞ + (y − y_∞)·e^(−b·dt),
// written with expm1 so that a short step loses no digits.
double FirstOrderStep(double y, double a, double b, double dt_s) {
  const double y_inf = a / b;
  return y + (y_inf - y) * -std::expm1(-b * dt_s);
}

// The fitness equation's coefficients: dx/dt = a − b·x.
struct Coefficients {
  double a, b;
};
Coefficients FitnessCoefficients(const StrengthParameters& p, double f) {
  const double recovery = (1.0 - p.recovery_gating * f) / p.recovery_time_s;
  const double fatigue = f / p.fatigue_time_s;
  return {p.min_fitness * fatigue + recovery, fatigue + recovery};
}
Coefficients PotentiationCoefficients(const StrengthParameters& p, double f) {
  const double build = f / p.potentiation_time_s;
  return {p.potentiation_max * build, build + 1.0 / p.potentiation_decay_s};
}

}  // namespace

StrengthParameters StrengthParameters::FirstOrder(double rate_per_s, double recovery_s,
                                                  double potentiation_max,
                                                  double potentiation_rate_per_s,
                                                  double potentiation_decay_s) {
  StrengthParameters p;
  p.fatigue_time_s = 1.0 / rate_per_s;
  p.recovery_time_s = recovery_s;
  p.min_fitness = 0.0;
  p.recovery_gating = 0.0;
  p.potentiation_max = potentiation_max;
  p.potentiation_time_s = 1.0 / potentiation_rate_per_s;
  p.potentiation_decay_s = potentiation_decay_s;
  return p;
}

double StrengthFactor(const StrengthState& state) {
  return state.fitness * (1.0 + state.potentiation);
}

StrengthModel::StrengthModel(const StrengthParameters& p) : parameters_(p) {
  const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(p.fatigue_time_s) || !positive(p.recovery_time_s) ||
      !positive(p.potentiation_time_s) || !positive(p.potentiation_decay_s) ||
      !std::isfinite(p.min_fitness) || p.min_fitness < 0.0 || p.min_fitness >= 1.0 ||
      !std::isfinite(p.recovery_gating) || p.recovery_gating < 0.0 || p.recovery_gating > 1.0 ||
      !std::isfinite(p.potentiation_max) || p.potentiation_max < 0.0) {
    throw std::invalid_argument(
        "strength: need time constants > 0, 0 ≤ x_min < 1, 0 ≤ γ ≤ 1 and P_max ≥ 0");
  }
}

StrengthState StrengthModel::Propagate(const StrengthState& state, double activation,
                                       double dt_s) const {
  if (!std::isfinite(activation) || !std::isfinite(dt_s) || dt_s < 0.0) {
    throw std::invalid_argument("strength: need a finite activation and dt ≥ 0");
  }
  const double f = std::clamp(activation, 0.0, 1.0);
  StrengthState out;
  // b > 0 always: the fitness's b ≥ min(1/T_fat, 1/T_rec) for f in [0, 1].
  const Coefficients x = FitnessCoefficients(parameters_, f);
  out.fitness = FirstOrderStep(state.fitness, x.a, x.b, dt_s);
  const Coefficients p = PotentiationCoefficients(parameters_, f);
  out.potentiation = FirstOrderStep(state.potentiation, p.a, p.b, dt_s);
  return out;
}

StrengthState StrengthModel::Steady(double activation) const {
  const double f = std::clamp(activation, 0.0, 1.0);
  const Coefficients x = FitnessCoefficients(parameters_, f);
  const Coefficients p = PotentiationCoefficients(parameters_, f);
  return {x.a / x.b, p.a / p.b};
}

double StrengthModel::FitnessTimeConstant(double activation) const {
  return 1.0 / FitnessCoefficients(parameters_, std::clamp(activation, 0.0, 1.0)).b;
}

}  // namespace fesbench::model
