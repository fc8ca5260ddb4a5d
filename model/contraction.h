#pragma once

/// @file
/// Linear contraction dynamics of the Hammerstein activation (thesis §3.2,
/// Fig. 3-6; Eqs. 3.21, 4.1–4.4; docs/MODEL.md):
///   H_n(s) = aⁿ / (s + a)ⁿ,  n = 2 or 3, unit DC gain,
/// realised as a chain of n identical first-order lags
///   ẋ₁ = −a·x₁ + a·v,  ẋ_k = −a·x_k + a·x_{k−1} (k = 2..n),  f_stim = x_n,
/// driven by the stimulator's pulse train: pulse k with amplitude u_k is an
/// impulse of weight R(u_k) / f_pulse, i.e. a jump of a·R(u_k)/f_pulse in x₁.
/// A steady train at amplitude u then settles (on average over a pulse
/// period) at f_stim = R(u), and a single pulse gives the twitch
/// h_n(t)·R(u)/f_pulse, which peaks at (n − 1)/a.

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <span>
#include <vector>

#include "model/parameter_set.h"
#include "model/piecewise_linear.h"
#include "model/signal.h"

namespace fesbench::model {

/// Largest contraction order supported (n ∈ {2, 3}).
inline constexpr int kMaxContractionOrder = 3;

/// Default stimulator pulse rate, Hz (§5.1).
inline constexpr double kDefaultPulseRateHz = 33.0;

/// The chain state x₁..x_n; entries beyond the order are kept at 0.
using ContractionState = std::array<double, kMaxContractionOrder>;

/// State-space form ẋ = A·x + B·v, f_stim = C·x of H_n (n×n, n×1, 1×n).
struct ContractionStateSpace {
  Eigen::MatrixXd a;
  Eigen::VectorXd b;
  Eigen::RowVectorXd c;
};

/// @throws std::invalid_argument unless order ∈ {2, 3} and pole_per_s is
///   finite and > 0 (the message names the offending field).
void ValidateContraction(const ContractionParams& contraction);

/// Unit-area impulse response h_n(t) = aⁿ·t^(n−1)·e^(−a·t) / (n − 1)!
/// (Eqs. 3.21, 4.1, 4.3 normalised to unit area), 0 for t < 0. Units s⁻¹.
/// @throws std::invalid_argument as ValidateContraction.
double ImpulseResponse(const ContractionParams& contraction, double t_s);

/// Time of the impulse-response peak, (n − 1)/a in s (Eqs. 4.2, 4.4).
/// @throws std::invalid_argument as ValidateContraction.
double ImpulseResponsePeakTime(const ContractionParams& contraction);

/// The chain realisation of H_n as Eigen matrices.
/// @throws std::invalid_argument as ValidateContraction.
ContractionStateSpace MakeContractionStateSpace(const ContractionParams& contraction);

/// Exact zero-input propagation of the chain over dt ≥ 0 for a fixed pole:
/// x(t + dt) = e^(A·dt)·x(t), with e^(A·dt) the lower-triangular Toeplitz
/// matrix e^(−a·dt)·(a·dt)^(i−j)/(i−j)! of the repeated pole. Caches the
/// factors of the last two distinct dt, so repeated equal steps cost a few
/// multiplications and no exp(). Not thread-safe (holds the cache); one per
/// simulation.
class ContractionPropagator {
 public:
  /// @throws std::invalid_argument as ValidateContraction.
  explicit ContractionPropagator(const ContractionParams& contraction);

  int order() const { return order_; }
  double pole_per_s() const { return pole_per_s_; }

  /// e^(A·dt) of one dt: the factors e^(−a·dt)·(a·dt)^k / k!, k = 0 … 2.
  struct Step {
    std::array<double, kMaxContractionOrder> coeff{};
  };
  /// The step of dt ≥ 0 (not checked), through the cache: a loop of equal
  /// steps (the RK4 loop of an interval, simulate.h) looks it up once.
  Step StepFor(double dt_s) { return {FactorsFor(dt_s).coeff}; }
  /// e^(A·dt)·x for a step from StepFor: the lower-triangular Toeplitz
  /// matrix of the repeated pole applied to x.
  ContractionState Propagate(const ContractionState& x, const Step& step) const {
    const auto& c = step.coeff;
    ContractionState y{};
    y[0] = c[0] * x[0];
    y[1] = c[0] * x[1] + c[1] * x[0];
    if (order_ == 3) y[2] = c[0] * x[2] + c[1] * x[1] + c[2] * x[0];
    return y;
  }
  /// The steps of h/2 and h (h ≥ 0, not checked) from one exp(), outside
  /// the cache: e^(−a·h) = (e^(−a·h/2))², the same up to rounding. For a
  /// step that is not repeated (an interval split by a pulse).
  struct HalfAndFull {
    Step half, full;
  };
  HalfAndFull StepsFor(double h_s) const {
    const double ah = pole_per_s_ * h_s, decay_half = std::exp(-0.5 * ah);
    const double decay = decay_half * decay_half;
    return {{{decay_half, decay_half * (0.5 * ah), decay_half * (0.125 * ah * ah)}},
            {{decay, decay * ah, decay * ah * ah / 2.0}}};
  }
  /// C·e^(A·dt)·x for a step from StepFor: the output row of Propagate
  /// alone (the RK4 loop's activation at the half step).
  double OutputAfter(const ContractionState& x, const Step& step) const {
    const auto& c = step.coeff;
    if (order_ == 2) return c[0] * x[1] + c[1] * x[0];
    return c[0] * x[2] + c[1] * x[1] + c[2] * x[0];
  }
  /// e^(A·dt)·x. dt must be ≥ 0 (not checked: internal hot path).
  ContractionState Propagate(const ContractionState& x, double dt_s) {
    return Propagate(x, StepFor(dt_s));
  }
  /// C·e^(A·dt)·x, the activation dt after the state x (no pulse between).
  double OutputAfter(const ContractionState& x, double dt_s);
  /// f_stim = x_n.
  double Output(const ContractionState& x) const { return x[order_ - 1]; }
  /// The jump of one pulse: x₁ += a·weight (an impulse of that weight).
  void ApplyImpulse(ContractionState& x, double weight) const { x[0] += pole_per_s_ * weight; }

 private:
  struct Factors {
    double dt_s = -1.0;
    std::array<double, kMaxContractionOrder> coeff{};  // e^(−a·dt)·(a·dt)^k / k!
  };
  const Factors& FactorsFor(double dt_s);

  int order_;
  double pole_per_s_;
  std::array<Factors, 2> cache_;
  int next_slot_ = 0;
};

/// Impulse weight of one pulse of amplitude stim_ma: R(u)/f_pulse (s).
/// A negative R (an artefact of a fitted curve) is clamped to 0.
double PulseWeight(const PiecewiseLinear& irc, double stim_ma, double pulse_rate_hz);

/// @throws std::invalid_argument if a pulse time or amplitude is not finite,
///   a time is negative, an amplitude is negative, or the times are not
///   strictly increasing (the message names the pulse index).
void ValidatePulseTrain(const PulseTrain& pulses);

/// f_stim(t) of the Hammerstein model (Fig. 3-6) at the given sample times,
/// from rest at t = 0, computed exactly (closed-form propagation between
/// pulses). A pulse at exactly a sample time is included (f_stim itself is
/// continuous for n ≥ 2, so this does not change the value).
/// @param irc R(u): stim_ma → activation.
/// @param pulse_rate_hz f_pulse > 0, Hz (33 Hz by default on the bench).
/// @param t_s sample times, s, non-decreasing, finite.
/// @throws std::invalid_argument on an invalid contraction, an empty irc,
///   pulse_rate_hz not finite or ≤ 0, an invalid pulse train
///   (ValidatePulseTrain) or decreasing / non-finite sample times.
std::vector<double> ActivationAt(const ContractionParams& contraction, const PiecewiseLinear& irc,
                                 const PulseTrain& pulses, double pulse_rate_hz,
                                 std::span<const double> t_s);

}  // namespace fesbench::model
