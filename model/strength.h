#pragma once

/// @file
/// Muscle strength that changes with use (beyond the thesis; docs/MODEL.md,
/// "Strength that changes with use"). The thesis's model is time-invariant;
/// §7.6.5 names the remedy: "a slowly decaying multiplicative term into the
/// active torque block", with fatigue and potentiation (§3.3) as its causes.
/// Here that term is
///
///   τ_act = s(t) · τ_scale · f_stim · f_ata(θ) · f_atv(θ̇),   s = x · (1 + P),
///
/// with the fitness x (1: rested, fatigue F = 1 − x) and the potentiation P
/// driven by the activation f ∈ [0, 1] the stimulation asks for (a steady
/// train at amplitude u: f = R(u), docs/MODEL.md "Activation under a pulse
/// train"):
///
///   dx/dt = (x_min − x) · f / T_fat + (1 − x) · (1 − γ·f) / T_rec
///   dP/dt = (P_max − P) · f / T_pot − P / T_pd
///
/// γ = 1 is Riener's fitness function (recovery only while not stimulated);
/// γ = 0 with x_min = 0 is the first-order form dF/dt = f·(1 − F)/T_fat −
/// F/T_rec. For constant f both equations are linear with constant
/// coefficients, dy/dt = a − b·y, so an interval of constant activation
/// (a steady pulse train, or none) is propagated exactly:
///
///   y(t + Δt) = y_∞ + (y(t) − y_∞) · e^(−b·Δt),   y_∞ = a / b.

namespace fesbench::model {

struct StrengthParameters {
  /// T_fat: fatigue time constant at full activation (f = 1), s, > 0.
  double fatigue_time_s = 30.0;
  /// T_rec: recovery time constant at rest, s, > 0.
  double recovery_time_s = 50.0;
  /// x_min: the fitness a muscle stimulated without end tends to, in [0, 1).
  double min_fitness = 0.05;
  /// γ ∈ [0, 1]: recovery proceeds at (1 − γ·f) of its rate while stimulated.
  double recovery_gating = 1.0;
  /// P_max ≥ 0 (0: no potentiation), its build-up time T_pot at full
  /// activation and its decay time T_pd, s, > 0.
  double potentiation_max = 0.0;
  double potentiation_time_s = 2.0;
  double potentiation_decay_s = 60.0;

  /// Literature priors for the quadriceps under surface stimulation at
  /// 20–50 Hz (docs/MODEL.md, "Strength that changes with use"): Riener's
  /// fitness function with T_fat = 30 s, T_rec = 50 s, x_min = 0.05, γ = 1;
  /// no potentiation. These are the defaults above.
  static StrengthParameters RienerPrior() { return {}; }
  /// The first-order form dF/dt = rate·f·(1 − F) − F/recovery_s (x_min = 0,
  /// γ = 0), with the optional potentiation dP/dt = rate_p·f·(P_max − P) −
  /// P/decay_s.
  static StrengthParameters FirstOrder(double rate_per_s, double recovery_s,
                                       double potentiation_max = 0.0,
                                       double potentiation_rate_per_s = 0.5,
                                       double potentiation_decay_s = 60.0);
};

struct StrengthState {
  double fitness = 1.0;       ///< x = 1 − F, in [x_min, 1] once started there.
  double potentiation = 0.0;  ///< P, in [0, P_max].
};

/// s = x · (1 + P), the factor on the active torque.
double StrengthFactor(const StrengthState& state);

/// The strength equations above, propagated in closed form.
class StrengthModel {
 public:
  /// @throws std::invalid_argument for parameters that are not finite or out
  ///   of the ranges stated in StrengthParameters.
  explicit StrengthModel(const StrengthParameters& parameters);

  /// The state after dt_s ≥ 0 s of constant activation f (clamped to [0, 1]).
  /// @throws std::invalid_argument for a non-finite f or dt_s < 0.
  StrengthState Propagate(const StrengthState& state, double activation, double dt_s) const;
  /// The equilibrium under constant activation f (y_∞ of both states).
  StrengthState Steady(double activation) const;
  /// 1/b of the fitness equation under constant activation f: the time
  /// constant of its approach to Steady(f).
  double FitnessTimeConstant(double activation) const;

  const StrengthParameters& parameters() const { return parameters_; }

 private:
  StrengthParameters parameters_;
};

}  // namespace fesbench::model
