#include "model/simulate.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "model/strength_history.h"
#include "model/units.h"

namespace fesbench::model {
namespace {

void RequirePositive(double v, const char* field) {
  if (!std::isfinite(v) || !(v > 0.0)) {
    throw std::invalid_argument(std::string("simulation: ") + field + " must be finite and > 0");
  }
}

// The angles a real knee takes: hyperextension to −30°, flexion to 180°
// (docs/ARCHITECTURE.md, units and sign conventions).
constexpr double kMinAngleDeg = -30.0;
constexpr double kMaxAngleDeg = 180.0;

void RequireAngle(double angle_deg, const char* field) {
  if (!std::isfinite(angle_deg) || angle_deg < kMinAngleDeg || angle_deg > kMaxAngleDeg) {
    throw std::invalid_argument(std::string("simulation: ") + field +
                                " must be within -30-180 deg, got " + std::to_string(angle_deg));
  }
}

void ValidateLimits(const JointLimits& limits, double initial_angle_deg) {
  if (!std::isfinite(limits.min_angle_deg) || !std::isfinite(limits.max_angle_deg) ||
      limits.min_angle_deg < kMinAngleDeg || limits.max_angle_deg > kMaxAngleDeg ||
      !(limits.min_angle_deg < limits.max_angle_deg)) {
    throw std::invalid_argument(
        "simulation: joint_limits must satisfy -30 <= min_angle_deg < max_angle_deg <= 180");
  }
  if (initial_angle_deg < limits.min_angle_deg || initial_angle_deg > limits.max_angle_deg) {
    throw std::invalid_argument(
        "simulation: initial_angle_deg " + std::to_string(initial_angle_deg) +
        " is outside the joint limits " + std::to_string(limits.min_angle_deg) + "-" +
        std::to_string(limits.max_angle_deg) + " deg");
  }
}

// Parameter-set checks shared by every mode; returns the model.
JointModel PrepareModel(const ParameterSet& params, const SimulationOptions& options) {
  ValidateContraction(params.contraction);
  if (params.irc.empty()) throw std::invalid_argument("simulation: irc is empty");
  return JointModel::FromParameters(params, options.model_kind);
}

SimulationResult MakeResult(std::size_t n, double rate_hz, ModelKind kind) {
  SimulationResult r;
  r.model = kind;
  r.t_s.resize(n);
  for (std::size_t i = 0; i < n; ++i) r.t_s[i] = static_cast<double>(i) / rate_hz;
  for (auto* col : {&r.stim_ma, &r.angle_deg, &r.velocity_deg_s, &r.accel_deg_s2, &r.torque_nm,
                    &r.activation}) {
    col->assign(n, 0.0);
  }
  return r;
}

// The free swing's state (θ in deg, θ̇ in deg/s) as two scalars, for the
// integrators (integrators.h, simulate.h): component by component the same
// arithmetic as Eigen::Vector2d, so the same values, without the pair
// packed into one register between the RK4 stages (perf: the packing and
// its spills sat on the stages' dependency chain).
struct KneeState {
  double angle = 0.0, velocity = 0.0;
  double operator[](std::size_t i) const { return i == 0 ? angle : velocity; }
  static std::size_t size() { return 2; }
  friend KneeState operator+(const KneeState& a, const KneeState& b) {
    return {a.angle + b.angle, a.velocity + b.velocity};
  }
  friend KneeState operator-(const KneeState& a, const KneeState& b) {
    return {a.angle - b.angle, a.velocity - b.velocity};
  }
  friend KneeState operator*(double k, const KneeState& a) { return {k * a.angle, k * a.velocity}; }
};

// The strength on the active torque (SimulationOptions::strength): the
// activation the mechanics see is f_stim · s(t) / reference (τ_act is linear
// in f_stim). NoStrength leaves it untouched (the thesis's model).
struct NoStrength {
  static constexpr bool kOn = false;
  double Apply(double /*t*/, double activation) const { return activation; }
  double Factor(double /*t*/) const { return 1.0; }
};

class StrengthGain {
 public:
  static constexpr bool kOn = true;
  StrengthGain(const SimulationStrength& strength, const PiecewiseLinear& irc,
               const PulseTrain& pulses, double pulse_rate_hz)
      : model_(strength.parameters),
        trace_(model_, irc, pulses, pulse_rate_hz, strength.initial),
        inverse_reference_(1.0 / strength.reference_factor) {}
  StrengthGain(const StrengthGain&) = delete;
  StrengthGain& operator=(const StrengthGain&) = delete;
  double Factor(double t) const { return trace_.FactorAt(t) * inverse_reference_; }
  double Apply(double t, double activation) const { return activation * Factor(t); }

 private:
  StrengthModel model_;
  StrengthTrace trace_;  // points at model_
  double inverse_reference_;
};

// SimulateFreeSwing's integration (validated inputs, r sized), with the
// strength `gain`.
template <class Gain>
void RunFreeSwing(const JointModel& model, const ParameterSet& params, const PulseTrain& pulses,
                  const SimulationOptions& options, std::size_t n, SimulationResult& r,
                  const Gain& gain) {
  // State x = (θ in deg, θ̇ in deg/s); ẍ from J·θ̈ = −τ_pta − τ_ptv − τ_act (§3.4).
  using State = KneeState;
  JointModel::Segments segments;  // the look-ups follow the trajectory
  const auto rhs = [&model, &segments, &gain](double t, const State& x, double activation) {
    return State{x.velocity,
                 model.AccelerationDegS2(x.angle, x.velocity, gain.Apply(t, activation), segments)};
  };
  const std::optional<JointLimits>& limits = options.joint_limits;
  const auto record = [&](std::size_t i, double t, const State& x, double activation) {
    r.angle_deg[i] = x.angle;
    r.velocity_deg_s[i] = x.velocity;
    double accel =
        model.AccelerationDegS2(x.angle, x.velocity, gain.Apply(t, activation), segments);
    // Resting on a stop that the net torque pushes into: the stop holds.
    if (limits && ((x.angle <= limits->min_angle_deg && accel < 0.0) ||
                   (x.angle >= limits->max_angle_deg && accel > 0.0))) {
      accel = 0.0;
    }
    r.accel_deg_s2[i] = accel;
    r.activation[i] = activation;
    if constexpr (Gain::kOn) r.strength[i] = gain.Factor(t);
  };
  const IntegratorSettings settings{options.integrator, options.step_s, options.tolerances};
  IntegratorWorkspace ws;
  // Plastic stops (JointLimits): clamp the angle, drop the velocity into
  // the stop; without limits nothing moves.
  const auto stop = [&limits](State& x) {
    if (!limits) return false;
    if (x.angle < limits->min_angle_deg || (x.angle == limits->min_angle_deg && x.velocity < 0.0)) {
      x.angle = limits->min_angle_deg;
      x.velocity = std::max(x.velocity, 0.0);
      return true;
    }
    if (x.angle > limits->max_angle_deg || (x.angle == limits->max_angle_deg && x.velocity > 0.0)) {
      x.angle = limits->max_angle_deg;
      x.velocity = std::min(x.velocity, 0.0);
      return true;
    }
    return false;
  };
  const State x0{options.initial_angle_deg, options.initial_velocity_deg_s};
  if (model.has_scaled_tables()) {
    // Rk4Stages arranged for the stages' dependency chain (FreeSwingRk4Step).
    const auto step = [&model, &segments, &gain](const auto& /*rhs*/, const State& x, double ts,
                                                 double h, double a0, double a_half,
                                                 double a_end) {
      State y = x;
      if constexpr (Gain::kOn) {
        model.FreeSwingRk4Step(y.angle, y.velocity, h, gain.Apply(ts, a0),
                               gain.Apply(ts + 0.5 * h, a_half), gain.Apply(ts + h, a_end),
                               segments);
      } else {
        model.FreeSwingRk4Step(y.angle, y.velocity, h, a0, a_half, a_end, segments);
      }
      return y;
    };
    detail::RunPulseDriven(rhs, record, x0, params.contraction, params.irc, pulses,
                           options.pulse_rate_hz, options.output_rate_hz, n, settings, ws, stop,
                           step);
  } else {
    detail::RunPulseDriven(rhs, record, x0, params.contraction, params.irc, pulses,
                           options.pulse_rate_hz, options.output_rate_hz, n, settings, ws, stop);
  }
  r.stats = ws.stats;
}

}  // namespace

namespace detail {

double DefaultDuration(const PulseTrain& pulses) {
  return pulses.empty() ? 1.0 : pulses.back().t_s + 1.0;
}

std::size_t ValidateOptions(const SimulationOptions& options, double default_duration_s) {
  RequirePositive(options.step_s, "step_s");
  RequirePositive(options.output_rate_hz, "output_rate_hz");
  RequirePositive(options.pulse_rate_hz, "pulse_rate_hz");
  const double duration = options.duration_s.value_or(default_duration_s);
  RequirePositive(duration, "duration_s");
  if (options.integrator == IntegratorKind::kAdaptive) ValidateTolerances(options.tolerances);
  if (options.strength) {
    RequirePositive(options.strength->reference_factor, "strength.reference_factor");
    const StrengthState& s0 = options.strength->initial;
    if (!std::isfinite(s0.fitness) || s0.fitness < 0.0 || !std::isfinite(s0.potentiation) ||
        s0.potentiation < 0.0) {
      throw std::invalid_argument("simulation: strength.initial must be finite and >= 0");
    }
    const StrengthModel check(options.strength->parameters);  // throws on bad parameters
  }
  const double n = std::floor(duration * options.output_rate_hz + 1e-9);
  if (n > 1e9) throw std::invalid_argument("simulation: duration_s * output_rate_hz too large");
  return std::max<std::size_t>(1, static_cast<std::size_t>(n));
}

}  // namespace detail

std::vector<double> StimulusColumn(const PulseTrain& pulses, double pulse_rate_hz,
                                   const std::vector<double>& t_s) {
  // A train continues from one pulse to the next if they are one period
  // apart (1 µs slack); single pulses and the last pulse of a train do not.
  const double period_s = 1.0 / pulse_rate_hz;
  const auto continues = [&](std::size_t j) {
    return j + 1 < pulses.size() && pulses[j + 1].t_s - pulses[j].t_s < period_s + 1e-6;
  };
  std::vector<double> out(t_s.size(), 0.0);
  std::size_t p = 0;  // pulses before the current sample's start
  for (std::size_t i = 0; i < t_s.size(); ++i) {
    const double begin = t_s[i] - kPulseTimeToleranceS;
    const double span = i + 1 < t_s.size() ? t_s[i + 1] - t_s[i]
                        : i > 0            ? t_s[i] - t_s[i - 1]
                                           : period_s;
    const double end = t_s[i] + span - kPulseTimeToleranceS;
    while (p < pulses.size() && pulses[p].t_s < begin) ++p;
    std::size_t q = p;
    while (q < pulses.size() && pulses[q].t_s < end) ++q;
    if (q > p) {
      out[i] = pulses[q - 1].stim_ma;  // a pulse in this sample's interval
    } else if (p > 0 && continues(p - 1)) {
      out[i] = pulses[p - 1].stim_ma;  // between two pulses of a train
    }
  }
  return out;
}

SimulationResult SimulateFreeSwing(const ParameterSet& params, const PulseTrain& pulses,
                                   const SimulationOptions& options) {
  ValidatePulseTrain(pulses);
  const std::size_t n = detail::ValidateOptions(options, detail::DefaultDuration(pulses));
  RequireAngle(options.initial_angle_deg, "initial_angle_deg");
  if (!std::isfinite(options.initial_velocity_deg_s)) {
    throw std::invalid_argument("simulation: initial_velocity_deg_s must be finite");
  }
  if (options.joint_limits) ValidateLimits(*options.joint_limits, options.initial_angle_deg);
  const JointModel model = PrepareModel(params, options);

  SimulationResult r = MakeResult(n, options.output_rate_hz, model.kind());
  r.stim_ma = StimulusColumn(pulses, options.pulse_rate_hz, r.t_s);
  if (!options.strength) {
    RunFreeSwing(model, params, pulses, options, n, r, NoStrength{});
    return r;
  }
  const StrengthGain gain(*options.strength, params.irc, pulses, options.pulse_rate_hz);
  r.strength.assign(n, 0.0);
  RunFreeSwing(model, params, pulses, options, n, r, gain);
  return r;
}

SimulationResult SimulateIsometric(const ParameterSet& params, const PulseTrain& pulses,
                                   double angle_deg, const SimulationOptions& options) {
  ValidatePulseTrain(pulses);
  const std::size_t n = detail::ValidateOptions(options, detail::DefaultDuration(pulses));
  RequireAngle(angle_deg, "angle_deg");
  const JointModel model = PrepareModel(params, options);

  SimulationResult r = MakeResult(n, options.output_rate_hz, model.kind());
  r.stim_ma = StimulusColumn(pulses, options.pulse_rate_hz, r.t_s);
  r.activation = ActivationAt(params.contraction, params.irc, pulses, options.pulse_rate_hz, r.t_s);
  // Eqs. 3.18–3.20: τ = C₀·f_stim + C₁ with the τ_ptv(0) of §6.5 referencing.
  const double c0 = model.ActiveGain(angle_deg, 0.0);
  const double c1 = model.PassiveAngleTorque(angle_deg) + model.PassiveVelocityTorque(0.0);
  if (options.strength) {
    const StrengthGain gain(*options.strength, params.irc, pulses, options.pulse_rate_hz);
    r.strength.resize(n);
    for (std::size_t i = 0; i < n; ++i) r.strength[i] = gain.Factor(r.t_s[i]);
  }
  for (std::size_t i = 0; i < n; ++i) {
    r.angle_deg[i] = angle_deg;
    r.torque_nm[i] =
        c1 + c0 * (r.strength.empty() ? r.activation[i] : r.activation[i] * r.strength[i]);
  }
  return r;
}

SimulationResult SimulateTrajectory(const ParameterSet& params, const PulseTrain& pulses,
                                    const Trajectory& trajectory,
                                    const SimulationOptions& options) {
  ValidatePulseTrain(pulses);
  const std::size_t n = detail::ValidateOptions(options, trajectory.duration_s());
  const JointModel model = PrepareModel(params, options);

  SimulationResult r = MakeResult(n, options.output_rate_hz, model.kind());
  r.stim_ma = StimulusColumn(pulses, options.pulse_rate_hz, r.t_s);
  r.activation = ActivationAt(params.contraction, params.irc, pulses, options.pulse_rate_hz, r.t_s);
  if (options.strength) {
    const StrengthGain gain(*options.strength, params.irc, pulses, options.pulse_rate_hz);
    r.strength.resize(n);
    for (std::size_t i = 0; i < n; ++i) r.strength[i] = gain.Factor(r.t_s[i]);
  }
  for (std::size_t i = 0; i < n; ++i) {
    const double active = r.strength.empty() ? r.activation[i] : r.activation[i] * r.strength[i];
    const Kinematics k = trajectory.At(r.t_s[i]);
    if (!std::isfinite(k.velocity_deg_s) || !std::isfinite(k.accel_deg_s2)) {
      throw std::invalid_argument("simulation: trajectory gives a non-finite value at t = " +
                                  std::to_string(r.t_s[i]));
    }
    RequireAngle(k.angle_deg, "trajectory angle");
    r.angle_deg[i] = k.angle_deg;
    r.velocity_deg_s[i] = k.velocity_deg_s;
    r.accel_deg_s2[i] = k.accel_deg_s2;
    // Eq. 4.9 plus the active term: τ_motor = J·θ̈ + τ_ptv(θ̇) + τ_pta(θ) + τ_act.
    r.torque_nm[i] = model.inertia_kgm2() * DegToRad(k.accel_deg_s2) +
                     model.PassiveVelocityTorque(k.velocity_deg_s) +
                     model.PassiveAngleTorque(k.angle_deg) +
                     active * model.ActiveGain(k.angle_deg, k.velocity_deg_s);
  }
  return r;
}

}  // namespace fesbench::model
