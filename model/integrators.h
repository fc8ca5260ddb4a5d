#pragma once

/// @file
/// ODE integrators for ẋ = f(t, x), generic over the state type (Eigen
/// column vectors, fixed or dynamic size, or any type with their +, −,
/// scalar ×, [] and size(), such as the free swing's two scalars,
/// simulate.cc):
///   - fixed-step classical Runge–Kutta 4;
///   - adaptive embedded Dormand–Prince 5(4) (Hairer, Nørsett & Wanner,
///     "Solving ODEs I", §II.5) with mixed relative/absolute error control,
///     step rejection and minimum/maximum step.
/// Chosen per call through IntegratorSettings.

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace fesbench::model {

enum class IntegratorKind {
  kRk4,       ///< classical RK4 with a fixed (maximum) step.
  kAdaptive,  ///< Dormand–Prince 5(4) with error control.
};

/// "rk4" or "adaptive".
std::string_view IntegratorKindName(IntegratorKind kind);
/// Inverse of IntegratorKindName; nullopt for an unknown name.
std::optional<IntegratorKind> ParseIntegratorKind(std::string_view name);

/// Error control of the adaptive integrator. A step is accepted when the RMS
/// over components of err_i / (atol + rtol·max(|x_i|, |x_new_i|)) is ≤ 1.
struct AdaptiveTolerances {
  double rtol = 1e-6;           ///< relative tolerance, > 0.
  double atol = 1e-6;           ///< absolute tolerance in the state's units, > 0.
  double min_step_s = 1e-10;    ///< smallest step before giving up, > 0.
  double max_step_s = 0.05;     ///< largest step, ≥ min_step_s.
  long max_steps = 10'000'000;  ///< accepted + rejected steps per call, > 0.
};

/// @throws std::invalid_argument if a tolerance or step bound is not finite
///   and positive, max_step_s < min_step_s, or max_steps ≤ 0.
void ValidateTolerances(const AdaptiveTolerances& tol);

/// Which integrator, with its settings.
struct IntegratorSettings {
  IntegratorKind kind = IntegratorKind::kRk4;
  double step_s = 1e-3;  ///< RK4: the maximum step (intervals are split evenly).
  AdaptiveTolerances tolerances;
};

/// @throws std::invalid_argument if step_s is not finite and > 0, or the
///   tolerances are invalid (ValidateTolerances).
void ValidateIntegratorSettings(const IntegratorSettings& settings);

/// Counters, accumulated over calls.
struct IntegrationStats {
  long accepted_steps = 0;
  long rejected_steps = 0;
  long rhs_evaluations = 0;
};

/// Working state carried between calls (the adaptive step-size guess).
struct IntegratorWorkspace {
  double next_step_s = 0.0;  ///< ≤ 0: choose an initial step automatically.
  IntegrationStats stats;
};

/// One classical RK4 step of size h from (t, x).
template <class State, class Rhs>
State Rk4Step(const Rhs& f, double t, const State& x, double h) {
  const State k1 = f(t, x);
  const State k2 = f(t + 0.5 * h, State(x + (0.5 * h) * k1));
  const State k3 = f(t + 0.5 * h, State(x + (0.5 * h) * k2));
  const State k4 = f(t + h, State(x + h * k3));
  return x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
}

/// Number of equal steps of at most max_step covering a span (a span that is
/// a whole multiple of max_step up to rounding gets exactly that many).
inline long EvenStepCount(double span_s, double max_step_s) {
  return std::max(1L, static_cast<long>(std::ceil(span_s / max_step_s - 1e-9)));
}

/// RK4 from t0 to t1 ≥ t0 in ⌈(t1 − t0)/max_step⌉ equal steps.
template <class State, class Rhs>
State IntegrateRk4(const Rhs& f, double t0, double t1, State x, double max_step_s,
                   IntegrationStats* stats = nullptr) {
  if (!(t1 > t0)) return x;
  const long n = EvenStepCount(t1 - t0, max_step_s);
  const double h = (t1 - t0) / static_cast<double>(n);
  for (long i = 0; i < n; ++i) x = Rk4Step(f, t0 + static_cast<double>(i) * h, x, h);
  if (stats != nullptr) {
    stats->accepted_steps += n;
    stats->rhs_evaluations += 4 * n;
  }
  return x;
}

namespace detail {

template <class State>
double ErrorNorm(const State& err, const State& x0, const State& x1,
                 const AdaptiveTolerances& tol) {
  double sum = 0.0;
  const auto n = err.size();
  for (decltype(err.size()) i = 0; i < n; ++i) {
    const double sc = tol.atol + tol.rtol * std::max(std::abs(x0[i]), std::abs(x1[i]));
    const double r = err[i] / sc;
    sum += r * r;
  }
  return std::sqrt(sum / static_cast<double>(n));
}

}  // namespace detail

/// The projection that leaves every state as it is (see
/// IntegrateDormandPrince45).
struct NoProjection {
  template <class State>
  bool operator()(State& /*x*/) const {
    return false;
  }
};

/// Dormand–Prince 5(4) from t0 to t1 ≥ t0, local extrapolation (the 5th-order
/// solution is propagated), FSAL, step controller
/// h ← h·clamp(0.9·err^(−1/5), 0.2, 5). workspace.next_step_s is used as the
/// first step (chosen from ‖x‖/‖f‖ when ≤ 0) and receives the step to try
/// next; the last step is shortened to land on t1 exactly. After each
/// accepted step `project(x)` may move the state onto a constraint (a joint
/// stop) and returns whether it did; the FSAL derivative is then re-evaluated.
/// @throws std::runtime_error if the step needed falls below min_step_s, the
///   state becomes non-finite, or max_steps is exceeded. Tolerances are not
///   validated here (see ValidateTolerances).
template <class State, class Rhs, class Project = NoProjection>
State IntegrateDormandPrince45(const Rhs& f, double t0, double t1, State x,
                               const AdaptiveTolerances& tol, IntegratorWorkspace& ws,
                               const Project& project = {}) {
  if (!(t1 > t0)) return x;
  // Butcher tableau (Dormand & Prince 1980).
  constexpr double c2 = 1.0 / 5, c3 = 3.0 / 10, c4 = 4.0 / 5, c5 = 8.0 / 9;
  constexpr double a21 = 1.0 / 5;
  constexpr double a31 = 3.0 / 40, a32 = 9.0 / 40;
  constexpr double a41 = 44.0 / 45, a42 = -56.0 / 15, a43 = 32.0 / 9;
  constexpr double a51 = 19372.0 / 6561, a52 = -25360.0 / 2187, a53 = 64448.0 / 6561,
                   a54 = -212.0 / 729;
  constexpr double a61 = 9017.0 / 3168, a62 = -355.0 / 33, a63 = 46732.0 / 5247, a64 = 49.0 / 176,
                   a65 = -5103.0 / 18656;
  constexpr double b1 = 35.0 / 384, b3 = 500.0 / 1113, b4 = 125.0 / 192, b5 = -2187.0 / 6784,
                   b6 = 11.0 / 84;
  // e = b(5th) − b(4th).
  constexpr double e1 = 71.0 / 57600, e3 = -71.0 / 16695, e4 = 71.0 / 1920, e5 = -17253.0 / 339200,
                   e6 = 22.0 / 525, e7 = -1.0 / 40;

  double t = t0;
  State k1 = f(t, x);
  ws.stats.rhs_evaluations += 1;
  double h = ws.next_step_s;
  if (!(h > 0.0)) {
    // Initial guess (Hairer §II.4): h = 0.01·‖x‖/‖f‖ in the tolerance scale.
    const State zero = x - x;
    const double d0 = detail::ErrorNorm(x, zero, zero, tol);
    const double d1 = detail::ErrorNorm(k1, zero, zero, tol);
    h = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
  }
  h = std::clamp(h, tol.min_step_s, tol.max_step_s);
  long steps = 0;
  while (t < t1) {
    if (++steps > tol.max_steps) {
      throw std::runtime_error("Dormand-Prince 5(4): more than max_steps steps");
    }
    // Land on t1 exactly; absorb a remainder too small to be a step.
    const bool last = t + h >= t1 - 1e-12 * std::max(1.0, std::abs(t1));
    const double hs = last ? t1 - t : h;
    const State k2 = f(t + c2 * hs, State(x + hs * (a21 * k1)));
    const State k3 = f(t + c3 * hs, State(x + hs * (a31 * k1 + a32 * k2)));
    const State k4 = f(t + c4 * hs, State(x + hs * (a41 * k1 + a42 * k2 + a43 * k3)));
    const State k5 = f(t + c5 * hs, State(x + hs * (a51 * k1 + a52 * k2 + a53 * k3 + a54 * k4)));
    const State k6 =
        f(t + hs, State(x + hs * (a61 * k1 + a62 * k2 + a63 * k3 + a64 * k4 + a65 * k5)));
    const State x_new = x + hs * (b1 * k1 + b3 * k3 + b4 * k4 + b5 * k5 + b6 * k6);
    const State k7 = f(t + hs, x_new);
    ws.stats.rhs_evaluations += 6;
    const State err = hs * (e1 * k1 + e3 * k3 + e4 * k4 + e5 * k5 + e6 * k6 + e7 * k7);
    const double en = detail::ErrorNorm(err, x, x_new, tol);
    if (!std::isfinite(en)) {
      throw std::runtime_error("Dormand-Prince 5(4): non-finite state at t = " + std::to_string(t));
    }
    const double factor = std::clamp(0.9 * std::pow(std::max(en, 1e-10), -0.2), 0.2, 5.0);
    if (en <= 1.0) {
      ++ws.stats.accepted_steps;
      t = last ? t1 : t + hs;
      x = x_new;
      k1 = k7;  // FSAL
      if (project(x)) {
        k1 = f(t, x);
        ws.stats.rhs_evaluations += 1;
      }
      // A shortened last step that passed easily says nothing against h.
      h = (last && factor >= 1.0) ? std::max(h, hs * factor) : hs * factor;
      h = std::clamp(h, tol.min_step_s, tol.max_step_s);
    } else {
      ++ws.stats.rejected_steps;
      if (hs <= tol.min_step_s) {
        throw std::runtime_error("Dormand-Prince 5(4): step below min_step_s at t = " +
                                 std::to_string(t));
      }
      h = std::max(hs * factor, tol.min_step_s);
    }
  }
  ws.next_step_s = h;
  return x;
}

/// Integrates from t0 to t1 with the integrator the settings choose.
/// @throws std::runtime_error as IntegrateDormandPrince45 (adaptive only).
template <class State, class Rhs>
State Integrate(const Rhs& f, double t0, double t1, State x, const IntegratorSettings& settings,
                IntegratorWorkspace& ws) {
  if (settings.kind == IntegratorKind::kRk4) {
    return IntegrateRk4(f, t0, t1, std::move(x), settings.step_s, &ws.stats);
  }
  return IntegrateDormandPrince45(f, t0, t1, std::move(x), settings.tolerances, ws);
}

}  // namespace fesbench::model
