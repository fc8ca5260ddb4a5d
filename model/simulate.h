#pragma once

/// @file
/// Forward simulation of the muscle–tendon–joint model (thesis ch. 3,
/// Fig. 3-9; docs/MODEL.md) under a stimulation pulse train, in the bench's
/// three modes: free swing (motor off), isometric (angle held) and
/// trajectory (motor imposes θ(t), §4.2.2).
///
/// Method. The activation f_stim is linear in the pulses and is computed
/// exactly: the contraction chain is propagated in closed form between
/// events and each pulse jumps its first state at the pulse's exact time
/// (contraction.h). Only the mechanics (θ, θ̇) are integrated numerically,
/// and every integration interval ends at each pulse time and each output
/// time, so no step straddles a pulse. With RK4 an interval is cut into
/// ⌈span/step_s⌉ equal steps (200 Hz output and a 1 ms step give exactly the
/// 1 kHz grid); the adaptive integrator restarts at each event with its
/// last step-size estimate.
///
/// Time starts at t = 0 with the muscle at rest (f_stim = 0). Output samples
/// are at t_i = i / output_rate_hz for i = 0 … N − 1, N = ⌊duration·rate⌋
/// (at least 1), i.e. they cover [0, duration) like a recording.

#include <cstddef>
#include <optional>
#include <vector>

#include "model/contraction.h"
#include "model/integrators.h"
#include "model/joint_model.h"
#include "model/parameter_set.h"
#include "model/signal.h"
#include "model/strength.h"

namespace fesbench::model {

/// The mechanical range of motion of a free-swing simulation: hard stops at
/// which the knee stops dead (a plastic impact: the angle is held at the stop
/// and the velocity into it is removed). This models the bench's stops, a
/// stiff spring–damper near critical damping that does not rebound
/// (server/bench/simulated_bench.cc); the thesis's model has none (ch. 3), so
/// without limits an identified set whose curves stop at the edge of the
/// visited range can swing the knee round past 0° or 180°.
struct JointLimits {
  double min_angle_deg = 10.0;   ///< full extension stop, deg.
  double max_angle_deg = 110.0;  ///< flexion stop, deg, > min_angle_deg.
  friend bool operator==(const JointLimits&, const JointLimits&) = default;
};

/// A strength state on the active torque (model/strength.h; docs/MODEL.md,
/// "Strength that changes with use"): τ_act is multiplied by
/// s(t) / reference_factor, s = x·(1 + P) propagated from `initial` at t = 0
/// by the activation the simulated pulses ask for (model/strength_history.h:
/// R(u) of each pulse for one pulse period).
struct SimulationStrength {
  StrengthParameters parameters;
  StrengthState initial;
  /// The strength the parameter set's τ_scale was identified at (1: a rested
  /// leg), > 0: the set's τ_scale already holds it.
  double reference_factor = 1.0;
};

/// Options of every simulation mode.
struct SimulationOptions {
  IntegratorKind integrator = IntegratorKind::kRk4;
  double step_s = 1e-3;           ///< RK4 internal step (maximum), s, > 0.
  double output_rate_hz = 200.0;  ///< output sample rate, Hz, > 0.
  /// Simulated span, s, > 0. Unset: the trajectory's duration in trajectory
  /// mode, otherwise the last pulse's time + 1 s (1 s without pulses).
  std::optional<double> duration_s;
  double initial_angle_deg = 90.0;      ///< free swing θ(0), deg, −30–180.
  double initial_velocity_deg_s = 0.0;  ///< free swing θ̇(0), deg/s.
  double pulse_rate_hz =
      kDefaultPulseRateHz;  ///< f_pulse of the pulse weight R(u)/f_pulse, Hz, > 0.
  AdaptiveTolerances tolerances{1e-8, 1e-8, 1e-10, 0.01, 10'000'000};  ///< adaptive only.
  std::optional<ModelKind> model_kind;  ///< overrides params.model when set.
  /// Free swing only: hard stops (none when unset). With RK4 the stop is
  /// applied after every step; with the adaptive integrator after every
  /// accepted step.
  std::optional<JointLimits> joint_limits;
  /// The strength state (none when unset: s ≡ 1, the thesis's model).
  std::optional<SimulationStrength> strength;
};

/// Equal-length columns, one row per output sample.
struct SimulationResult {
  std::vector<double> t_s;
  /// The delivered stimulation as an envelope (StimulusColumn): the
  /// amplitude of the pulse in [t_i, t_{i+1}), else of the previous pulse
  /// while its train goes on, else 0. PulsesFromEnvelope of this column gives
  /// the pulses back (a single pulse is one sample, never two pulses).
  std::vector<double> stim_ma;
  std::vector<double> angle_deg;
  std::vector<double> velocity_deg_s;
  std::vector<double> accel_deg_s2;
  /// Brace torque, N·m, positive in flexion: 0 in free swing; isometric
  /// τ_pta(θ₀) + τ_ptv(0) + τ_act (raw, offset not removed); trajectory
  /// J·θ̈ + τ_pta(θ) + τ_ptv(θ̇) + τ_act (Eq. 4.9 plus the active term).
  std::vector<double> torque_nm;
  std::vector<double> activation;      ///< f_stim (dimensionless), before the strength.
  /// With SimulationOptions::strength: s(t) / reference_factor at each
  /// sample, the factor on τ_act; empty otherwise.
  std::vector<double> strength;
  ModelKind model = ModelKind::kFull;  ///< the variant simulated.
  IntegrationStats stats;              ///< free swing only; zeros otherwise.

  std::size_t size() const { return t_s.size(); }
};

/// Free swing: motor off, J·θ̈ = −τ_pta(θ) − τ_ptv(θ̇) − τ_act, inside
/// options.joint_limits when set (at a stop with the net torque pushing into
/// it, θ̇ = θ̈ = 0).
/// @throws std::invalid_argument on invalid options (non-finite or
///   non-positive step, rate, duration, pulse rate, tolerances; initial
///   angle outside 0–180° or outside the joint limits, non-finite
///   velocity, joint limits not finite or not 0 ≤ min < max ≤ 180), an
///   invalid pulse train
///   (non-finite, negative, or non-increasing times; negative amplitudes),
///   or an invalid parameter set (contraction, empty irc, JointModel); the
///   message names the field.
/// @throws std::runtime_error if the adaptive integrator fails (step below
///   its minimum, non-finite state).
SimulationResult SimulateFreeSwing(const ParameterSet& params, const PulseTrain& pulses,
                                   const SimulationOptions& options);

/// Isometric: θ ≡ angle_deg; the torque column is the raw brace reading
/// τ_pta(θ₀) + τ_ptv(0) + τ_scale·f_ata(θ₀)·f_atv(0)·f_stim (Eqs. 3.18–3.20).
/// @throws std::invalid_argument as SimulateFreeSwing, and if angle_deg is
///   not in 0–180.
SimulationResult SimulateIsometric(const ParameterSet& params, const PulseTrain& pulses,
                                   double angle_deg, const SimulationOptions& options);

/// Trajectory (motor) mode: θ(t) imposed; the torque column is the torque
/// the brace must apply, J·θ̈ + τ_pta(θ) + τ_ptv(θ̇) + τ_act (Eq. 4.9 with
/// the active term), θ̈ converted to rad/s².
/// @throws std::invalid_argument as SimulateFreeSwing, and if the
///   trajectory gives a non-finite value or an angle outside 0–180 at an
///   output time.
SimulationResult SimulateTrajectory(const ParameterSet& params, const PulseTrain& pulses,
                                    const Trajectory& trajectory, const SimulationOptions& options);

/// The stim_ma column of SimulationResult, also the stim_delivered_ma
/// channel of a bench trial (server/protocols/runner.cc): sample i, which
/// covers [t_i, t_{i+1}) (the last sample as long as the one before it),
/// reads the amplitude of the last pulse in that interval; without one, the
/// amplitude of the previous pulse if the next pulse follows it one pulse
/// period later (a train going on), else 0. A train thus reads as its
/// envelope from the sample of its first pulse to that of its last, and a
/// single pulse as one sample, so PulsesFromEnvelope of the column at a
/// sample rate above the pulse rate returns the pulses of the continuous
/// grid (docs/MODEL.md) and single pulses at sample times unchanged.
/// Sample times non-decreasing; pulses validated by the caller.
std::vector<double> StimulusColumn(const PulseTrain& pulses, double pulse_rate_hz,
                                   const std::vector<double>& t_s);

namespace detail {

/// Validates the shared options and returns the number of output samples.
/// `default_duration_s` is used when options.duration_s is unset.
std::size_t ValidateOptions(const SimulationOptions& options, double default_duration_s);

/// Default duration of free swing / isometric runs (see SimulationOptions).
double DefaultDuration(const PulseTrain& pulses);

/// RunPulseDriven's RK4 step: Rk4Step (integrators.h) written out with the
/// exact activation at t, t + h/2 and t + h (the only times RK4 samples the
/// input), the right-hand side called per stage.
struct Rk4Stages {
  template <class State, class Rhs>
  State operator()(const Rhs& rhs, const State& x, double ts, double h, double a0, double a_half,
                   double a_end) const {
    const State k1 = rhs(ts, x, a0);
    const State k2 = rhs(ts + 0.5 * h, State(x + (0.5 * h) * k1), a_half);
    const State k3 = rhs(ts + 0.5 * h, State(x + (0.5 * h) * k2), a_half);
    const State k4 = rhs(ts + h, State(x + h * k3), a_end);
    return x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
  }
};

/// Integrates a mechanical state driven by the exact activation of a pulse
/// train (see the file comment): rhs(t, x, f_stim) → ẋ; record(i, t_i, x,
/// f_stim) at each output time; project(x) after every step may move the
/// state onto a constraint (see IntegrateDormandPrince45); with RK4,
/// rk4_step(rhs, x, t, h, f_stim(t), f_stim(t + h/2), f_stim(t + h)) takes
/// one step (Rk4Stages, or the same step arranged for one right-hand side).
/// Inputs are assumed validated.
template <class State, class Rhs, class Record, class Project = NoProjection,
          class Step = Rk4Stages>
void RunPulseDriven(const Rhs& rhs, const Record& record, State x,
                    const ContractionParams& contraction, const PiecewiseLinear& irc,
                    const PulseTrain& pulses, double pulse_rate_hz, double output_rate_hz,
                    std::size_t n_out, const IntegratorSettings& settings, IntegratorWorkspace& ws,
                    const Project& project = {}, const Step& rk4_step = {}) {
  ContractionPropagator prop(contraction);
  ContractionState chain{};
  double t = 0.0;
  std::size_t p = 0;
  const auto apply_pulses_until = [&](double until_s) {
    while (p < pulses.size() && pulses[p].t_s <= until_s) {
      prop.ApplyImpulse(chain, PulseWeight(irc, pulses[p].stim_ma, pulse_rate_hz));
      ++p;
    }
  };
  // Advances from t to t_end with no pulse strictly inside.
  // The chain's factors for the full step and its half, kept apart from
  // the propagator's two-entry cache, which the shorter steps of the
  // intervals split by a pulse would otherwise evict at every pulse.
  const double step_s = settings.step_s;
  const ContractionPropagator::Step step_half = prop.StepFor(0.5 * step_s);
  const ContractionPropagator::Step step_full = prop.StepFor(step_s);
  // An output interval without a pulse (the most of them) is split the
  // same way every time: its step count and step computed once, so that no
  // division sits between one interval's last step and the next's first.
  const double out_span_s = 1.0 / output_rate_hz;
  const long out_m = EvenStepCount(out_span_s, step_s);
  const double out_h = out_span_s / static_cast<double>(out_m);
  const auto advance = [&](double t_end) {
    if (settings.kind == IntegratorKind::kRk4) {
      const double span = t_end - t;
      // Spans within 1e-12 relative of the output period (t_end − t of two
      // output times differs from it in the last bits) take its steps.
      const bool out_interval = std::abs(span - out_span_s) <= 1e-12 * out_span_s;
      const long m = out_interval ? out_m : EvenStepCount(span, step_s);
      const double h = out_interval ? out_h : span / static_cast<double>(m);
      const double t0 = t;
      // Every step of the interval has the same h: the chain's factors for
      // h/2 and h are looked up once (within 1e-12 relative, as the cache).
      const bool regular = std::abs(h - step_s) <= 1e-12 * step_s;
      const ContractionPropagator::HalfAndFull steps =
          regular ? ContractionPropagator::HalfAndFull{step_half, step_full} : prop.StepsFor(h);
      const ContractionPropagator::Step& half = steps.half;
      const ContractionPropagator::Step& full = steps.full;
      double a0 = prop.Output(chain);
      for (long k = 0; k < m; ++k) {
        const double ts = t0 + static_cast<double>(k) * h;
        // RK4 samples the input at t, t + h/2 and t + h only: the exact
        // activation there, once per step (the step's end is the next start).
        const ContractionState c_end = prop.Propagate(chain, full);
        const double a_half = prop.OutputAfter(chain, half), a_end = prop.Output(c_end);
        x = rk4_step(rhs, x, ts, h, a0, a_half, a_end);
        project(x);
        chain = c_end;
        a0 = a_end;
      }
      ws.stats.accepted_steps += m;
      ws.stats.rhs_evaluations += 4 * m;
    } else {
      const ContractionState c0 = chain;
      const double ts = t;
      const auto f = [&](double tt, const State& xx) {
        return rhs(tt, xx, prop.OutputAfter(c0, tt - ts));
      };
      x = IntegrateDormandPrince45(f, t, t_end, x, settings.tolerances, ws, project);
      chain = prop.Propagate(chain, t_end - t);
    }
    t = t_end;
  };
  apply_pulses_until(0.0);
  for (std::size_t i = 0; i < n_out; ++i) {
    const double ti = static_cast<double>(i) / output_rate_hz;
    while (t < ti) {
      const double seg_end = (p < pulses.size() && pulses[p].t_s < ti) ? pulses[p].t_s : ti;
      advance(seg_end);
      apply_pulses_until(t);
    }
    record(i, ti, x, prop.Output(chain));
  }
}

}  // namespace detail

}  // namespace fesbench::model
