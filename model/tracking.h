#pragma once

/// @file
/// Knee-angle tracking by stimulation (thesis §7.6.3, issue 19): the three
/// controllers a `tracking` run chooses from, one sample at a time, pure
/// (the loop that reads the bench and applies the amplitude through the
/// interlocks is server/protocols/runner.cc).
///
///  - `pid`: the clinic's baseline. The amplitude is the session's threshold
///    plus a PID on the angle error (model::Pid), no model inside the loop;
///    the gains are tuned from the parameter set (TuneGains).
///  - `inverse_model`: the feedforward of model::InvertModel (§7.6.3:
///    "Non-linear open-loop control can be tested by inverting the
///    non-linear dynamic model") with a PID around it ("A PID loop around
///    this non-linear compensator could help correct modeling errors").
///  - `adaptive`: the same, with the feedforward recomputed at every sample
///    from τ̂_scale, which a model::ScaleEstimator follows from the measured
///    motion (§7.6.3: "A simple adaptive scheme which updates the active gain
///    parameter τ_scale based on the system response may be enough to
///    compensate for short term fatigue or potentiation effects").
///
/// The estimator's regression τ_act = τ_scale·φ (model/inverse_model.h)
/// needs the measured θ̇ and θ̈ and the activation the commanded pulses
/// produce. The controller keeps both: a critically damped state-variable
/// filter (cut-off velocity_filter_hz) gives θ_f, θ̇_f, θ̈_f from the angle
/// samples, the Hammerstein chain (model/contraction.h) driven by the pulses
/// it commanded gives f_stim, and φ and the passive torques pass through the
/// same filter so both sides of the regression carry the same delay.

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>
#include <optional>
#include <string_view>

#include "model/contraction.h"
#include "model/inverse_model.h"
#include "model/joint_model.h"
#include "model/parameter_set.h"

namespace fesbench::model {

enum class ControllerKind { kPid, kInverseModel, kAdaptive };

/// "pid", "inverse_model", "adaptive".
std::string_view ControllerKindName(ControllerKind kind);
std::optional<ControllerKind> ControllerKindOf(std::string_view name);

struct TrackingOptions {
  ControllerKind kind = ControllerKind::kInverseModel;
  double pulse_rate_hz = kDefaultPulseRateHz;
  double threshold_ma = 0.0;        ///< the session's threshold: the PID's bias.
  double max_amplitude_ma = 100.0;  ///< the session's maximum tolerated.
  /// Unset: TuneGains(params, target, options).
  std::optional<Pid::Gains> gains;
  /// Forgetting factor of the τ_scale estimator (adaptive): the estimate
  /// weighs the last ≈ 1/((1 − λ)·rate) seconds (0.999 at 200 Hz: 5 s).
  double forgetting = 0.999;
  /// Cut-off of the state-variable filter of the measured angle, Hz.
  double velocity_filter_hz = 3.0;
  /// τ̂_scale stays within these fractions of the set's τ_scale.
  double min_scale_fraction = 0.3;
  double max_scale_fraction = 3.0;
};

/// The PID gains a tracking run uses when none are given, from the set's
/// static loop gain at the target's mid angle: g = K_u / K_θ (deg per mA),
/// with K_u = τ_scale·f_ata(θ_m)·ΔR/Δu (the recruitment's mean slope from
/// threshold to the maximum) and K_θ the slope of the total torque
/// τ_pta(θ) + f_m·τ_scale·f_ata(θ) at the holding activation f_m. The loop
/// gain kp·g is 0.5 for `pid` (the whole job) and 0.25 around a feedforward
/// (a correction); ki = kp / 1 s, kd = kp · 0.1 s. (On the example leg with
/// the model as plant, a 0.2 Hz sine 30–80°: loop gain 1 with ki = kp/0.6 s
/// and kd = kp·0.03 s diverges, and without kd any loop gain ≥ 0.5 with
/// ki = kp/0.3 s does; these values sit inside the stable region with margin
/// for a leg richer than its model.)
/// @throws std::invalid_argument as InvertModel.
Pid::Gains TuneGains(const ParameterSet& params, const KneeTarget& target,
                     const TrackingOptions& options);

/// What one control sample decided.
struct TrackingSample {
  double amplitude_ma = 0.0;    ///< commanded, in [0, max_amplitude_ma].
  double target_deg = 0.0;      ///< θ* at this sample.
  double error_deg = 0.0;       ///< θ − θ* (positive: too flexed).
  double feedforward_ma = 0.0;  ///< the model's amplitude (pid: the threshold bias).
  double correction_ma = 0.0;   ///< amplitude − feedforward.
  double tau_scale_nm = 0.0;    ///< τ̂_scale (the set's value unless adaptive).
  /// The output is held at the maximum while the knee is too flexed: the
  /// controller asks for more than it may give.
  bool saturated = false;
};

/// One tracking run's controller, sampled at the target's rate.
class TrackingController {
 public:
  /// @throws std::invalid_argument for an invalid set or target, options
  ///   out of range (threshold < 0, max < threshold, λ outside (0, 1],
  ///   filter ≤ 0).
  TrackingController(const ParameterSet& params, KneeTarget target, TrackingOptions options);

  /// The amplitude for sample index() given the knee angle measured now;
  /// then index() advances. Past the target's end the last target angle
  /// is held.
  TrackingSample Update(double measured_deg);

  std::size_t index() const { return index_; }
  const KneeTarget& target() const { return target_; }
  const Pid::Gains& gains() const { return gains_; }
  double tau_scale_nm() const { return tau_scale_; }

 private:
  double FeedforwardAt(std::size_t i) const;  // with the current τ̂
  void Observe(double measured_deg);

  ParameterSet params_;
  JointModel joint_;
  KneeTarget target_;
  TrackingOptions options_;
  Pid::Gains gains_;
  Pid pid_;
  std::vector<double> needed_torque_nm_;  // τ_act* along the target
  std::vector<double> curve_gain_;        // f_ata·f_atv along the target
  std::size_t lead_ = 0;                  // contraction lead n/a, samples
  double dt_s_;
  std::size_t index_ = 0;
  double tau_scale_;
  ScaleEstimator estimator_;
  // Measured-motion filter (θ_f, θ̇_f in deg, deg/s) and the same filter on
  // the regression's model side: passive torque and φ.
  std::array<double, 2> angle_filter_{};
  std::array<double, 2> passive_filter_{};
  std::array<double, 2> regressor_filter_{};
  bool filters_started_ = false;
  ContractionPropagator chain_;
  ContractionState activation_{};
  std::int64_t next_pulse_ = 0;  // index of the next pulse-clock tick
};

}  // namespace fesbench::model
