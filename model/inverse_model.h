#pragma once

/// @file
/// The model inverted for control (thesis §7.6.3: "Non-linear open-loop
/// control can be tested by inverting the non-linear dynamic model"): from
/// a target knee trajectory θ*(t), the stimulation that makes the model
/// follow it, and a PID loop to put around it.
///
/// The inverse, step by step, of the equation of motion (Eq. 3.16, sign
/// convention of model/joint_model.h, quadriceps torque extensor)
///   J·θ̈ = −τ_pta(θ) − τ_ptv(θ̇) − f_stim·τ_scale·f_ata(θ)·f_atv(θ̇):
///  1. the active torque the trajectory needs,
///       τ_act* = −J·θ̈* − τ_pta(θ*) − τ_ptv(θ̇*)  (θ̈* in rad/s²);
///  2. the activation, f_stim* = τ_act* / (τ_scale·f_ata(θ*)·f_atv(θ̇*)),
///     held to [0, 1] (below 0 the muscle cannot pull the knee into flexion;
///     above 1 it cannot pull harder): such samples are marked saturated;
///  3. the contraction dynamics H_n(s) = aⁿ/(s + a)ⁿ (Eq. 3.21) compensated
///     by their low-frequency inverse, a lead of their mean delay n/a:
///     the recruitment must reach f_stim*(t + n/a) at t. Exact for a
///     constant target, first order in ω·n/a otherwise (0.2 Hz, a = 25 s⁻¹,
///     n = 3: ω·n/a = 0.15);
///  4. the amplitude from the inverse recruitment curve, u = R⁻¹(f), the
///     smallest amplitude that recruits f (§4.1), capped at the session's
///     maximum;
///  5. one pulse per tick of the stimulator's continuous pulse clock
///     (docs/MODEL.md, pulse timing) with the amplitude at its time.

#include <cstddef>
#include <vector>

#include "model/contraction.h"
#include "model/parameter_set.h"
#include "model/piecewise_linear.h"
#include "model/signal.h"

namespace fesbench::model {

/// A target knee trajectory sampled uniformly from t = 0, with its
/// derivatives (deg, deg/s, deg/s²).
struct KneeTarget {
  double rate_hz = 200.0;
  std::vector<double> angle_deg;
  std::vector<double> velocity_deg_s;
  std::vector<double> accel_deg_s2;
  std::size_t size() const { return angle_deg.size(); }
  double duration_s() const;
};

/// θ*(t) = (lo + hi)/2 + (hi − lo)/2 · sin(2π·f·t), derivatives exact.
/// @throws std::invalid_argument unless lo < hi, f > 0, duration > 0,
///   rate > 0 (all finite).
KneeTarget SineTarget(double lo_deg, double hi_deg, double frequency_hz, double duration_s,
                      double rate_hz = 200.0);

/// Holds at each angle for hold_s, moving between them in move_s along a
/// raised cosine (zero velocity at both ends), derivatives exact.
/// @throws std::invalid_argument unless angles is not empty, hold_s ≥ 0,
///   move_s > 0, rate > 0 (all finite).
KneeTarget HoldsTarget(const std::vector<double>& angles_deg, double hold_s, double move_s,
                       double rate_hz = 200.0);

/// A target from angle samples (an uploaded trajectory): velocity and
/// acceleration by central differences (one-sided at the ends).
/// @throws std::invalid_argument for fewer than 3 samples, a non-finite
///   angle or rate_hz ≤ 0.
KneeTarget SampledTarget(std::vector<double> angle_deg, double rate_hz);

/// u = R⁻¹(f): the smallest amplitude whose recruitment is f on the rising
/// part of the curve (linear inside a segment). f ≤ 0 gives 0 mA (no
/// stimulation); f above the curve's top gives the amplitude where the top
/// is first reached.
/// @throws std::invalid_argument if the curve is empty.
double InverseRecruitment(const PiecewiseLinear& irc, double activation);

struct InverseOptions {
  double pulse_rate_hz = kDefaultPulseRateHz;
  double max_amplitude_ma = 100.0;  ///< the session's maximum tolerated.
  bool compensate_contraction = true;
};

/// The stimulation that makes the model follow a target.
struct Feedforward {
  std::vector<double> t_s;
  std::vector<double> active_torque_nm;  ///< τ_act*, N·m (extensor positive).
  std::vector<double> activation;        ///< f_stim*, held to [0, 1].
  std::vector<double> amplitude_ma;      ///< u(t), capped at the maximum.
  /// 1 where the target asks for what the model cannot give (activation
  /// outside [0, 1] or an amplitude above the maximum), else 0.
  std::vector<unsigned char> saturated;
  PulseTrain pulses;  ///< one per pulse-clock tick over the target.
};

/// Inverts `params`' model along `target` (file comment).
/// @throws std::invalid_argument for an empty target, an invalid parameter
///   set (JointModel::FromParameters) or options out of range.
Feedforward InvertModel(const ParameterSet& params, const KneeTarget& target,
                        const InverseOptions& options);

/// A discrete PID on the flexion error e = θ − θ* (deg) whose output, in
/// the unit of its gains' numerator, is a correction — of the amplitude (mA)
/// for the clinic's PID, of the extensor torque (N·m) around the inverted
/// model (model/tracking.h) — positive when the knee is too flexed (more
/// extension needed). Derivative on the measurement (no kick when the
/// target jumps), first-order filtered; the integral is frozen while the
/// output is saturated (anti-windup).
class Pid {
 public:
  struct Gains {
    double kp = 0.0;                    ///< output per deg.
    double ki = 0.0;                    ///< output per deg·s.
    double kd = 0.0;                    ///< output·s per deg.
    double derivative_filter_s = 0.02;  ///< time constant, s, ≥ 0.
  };
  /// @throws std::invalid_argument for a non-finite or negative gain, a
  ///   negative filter time, dt ≤ 0 or min > max.
  Pid(Gains gains, double dt_s, double min_out, double max_out);

  /// One control period: feedforward + the correction for target and
  /// measured angle, held to [min_out, max_out].
  double Update(double target_deg, double measured_deg, double feedforward = 0.0);
  /// New output bounds (e.g. what the actuator can give at this sample).
  /// @throws std::invalid_argument unless finite and min ≤ max.
  void SetLimits(double min_out, double max_out);
  void Reset();
  /// Multiplies kp, ki and kd by k (0 < k ≤ 1: a back-off), bumplessly:
  /// the integral's share of the output, ki·∫e, stays what it was.
  /// @throws std::invalid_argument unless 0 < k ≤ 1.
  void ScaleGains(double k);
  const Gains& gains() const { return gains_; }
  double integral() const { return integral_; }
  bool saturated() const { return saturated_; }
  /// The last output wanted more than max_out (its integral held just
  /// below, the output may sit a hair under the limit).
  bool saturated_high() const { return saturated_high_; }

 private:
  Gains gains_;
  double dt_s_;
  double min_out_;
  double max_out_;
  double integral_ = 0.0;
  double derivative_ = 0.0;
  double last_measured_ = 0.0;
  bool first_ = true;
  bool saturated_ = false;
  bool saturated_high_ = false;
};

/// The active gain τ_scale followed online (§7.6.3: "a simple adaptive
/// scheme which updates the active gain parameter τ_scale based on the
/// system response may be enough to compensate for short term fatigue or
/// potentiation"): scalar recursive least squares with exponential
/// forgetting on the regression τ_act = τ_scale·φ, where φ =
/// f_stim·f_ata(θ)·f_atv(θ̇) is the model's activation times its curves and
/// τ_act = −J·θ̈ − τ_pta(θ) − τ_ptv(θ̇) the active torque the measured motion
/// shows. With forgetting factor λ the estimate weighs the last ≈ 1/(1 − λ)
/// samples; samples with |φ| below `min_regressor` carry no information
/// about τ_scale and are skipped.
class ScaleEstimator {
 public:
  /// @throws std::invalid_argument unless initial_nm > 0, 0 < λ ≤ 1 and
  ///   initial_variance > 0 (all finite).
  ScaleEstimator(double initial_nm, double forgetting, double initial_variance = 100.0,
                 double min_regressor = 0.05);
  /// One sample; returns the new estimate (N·m, kept ≥ 0).
  double Update(double regressor, double active_torque_nm);
  double estimate_nm() const { return estimate_; }

 private:
  double estimate_;
  double forgetting_;
  double variance_;
  double min_regressor_;
};

}  // namespace fesbench::model
