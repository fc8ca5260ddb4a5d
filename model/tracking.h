#pragma once

/// @file
/// Knee-angle tracking by stimulation (thesis §7.6.3; docs/MODEL.md): the three
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
///    compensate for short term fatigue or potentiation effects"). The
///    estimate is of the gain g in τ_act = g·s(t)·τ_scale·φ, with s(t) the
///    strength state (model/strength.h) the commanded stimulation predicts:
///    §7.6.5's two remedies together (docs/MODEL.md, "Strength that changes
///    with use").
///
/// The estimator's regression τ_act = τ_scale·φ (model/inverse_model.h)
/// needs the measured θ̇ and θ̈ and the activation the commanded pulses
/// produce. The controller keeps both: a critically damped state-variable
/// filter (cut-off velocity_filter_hz) gives θ_f, θ̇_f, θ̈_f from the angle
/// samples, the Hammerstein chain (model/contraction.h) driven by the pulses
/// it commanded gives f_stim, and φ and the passive torques pass through the
/// same filter so both sides of the regression carry the same delay.

#include <array>
#include <complex>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "model/contraction.h"
#include "model/inverse_model.h"
#include "model/joint_model.h"
#include "model/parameter_set.h"
#include "model/strength.h"

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
  /// The strength state of the adaptive estimator (model/strength.h): the
  /// controller propagates s(t) from the activation it commands and
  /// estimates the gain g in τ_act = g·s(t)·τ_scale·φ, so the feedforward
  /// follows the fatigue the stimulation history predicts and the estimator
  /// only the prior's error. Unset: s ≡ 1 (τ_act = τ̂_scale·φ).
  std::optional<StrengthParameters> strength = StrengthParameters::RienerPrior();
};

/// The tracking loop linearised about a hold at the target's mean angle θ_m
/// (or at about_deg)
/// (per degree; the plant from the PID's output to the knee angle):
///   P(s) = plant_gain · H_n(s) · e^(−s·delay) / (J·s² + B·s + K),
/// with K and B the slopes of the model's angle and velocity torques
/// (passive plus the holding activation f_m's active part) at θ_m, H_n the
/// contraction dynamics (Eq. 3.21), and the delay one control sample of
/// computation, half a sample of hold and half a pulse period. plant_gain
/// is 1 for the torque PID around the compensator (`inverse_model`,
/// `adaptive`) and K_u = τ_scale·f_ata(θ_m)·dR/du for `pid`'s amplitude
/// PID, N·m/mA, with dR/du the recruitment's slope where it holds f_m
/// (PidRecruitmentSlope; docs/MODEL.md, "Tracking: pid's loop gain where it
/// holds"): the same linearisation about the hold as K and B.
/// The PID's shape: ki = kp/integral_s, kd = kp·derivative_s.
struct LoopShape {
  double inertia = 0.0;    ///< J, N·m·s²/deg.
  double damping = 0.0;    ///< B, N·m·s/deg.
  double stiffness = 0.0;  ///< K, N·m/deg (at least 0.05).
  double pole_per_s = 1.0;
  int order = 2;
  double delay_s = 0.0;
  double plant_gain = 1.0;
  double integral_s = 1.0;
  double derivative_s = 0.0;
  double derivative_filter_s = 0.02;
};

/// Gain margin of the tuned loops (6 dB, the textbook value). On the 16
/// simulated legs of the study with their model part as the set, 2.5 left
/// 0.1° more RMS on a sine and 1.3 no oscillation but less margin for a
/// set identified from trials.
inline constexpr double kGainMargin = 2.0;

/// The chord over which PidRecruitmentSlope measures the slope, mA.
inline constexpr double kPidSlopeChordMa = 1.0;

/// The recruitment's slope `pid`'s loop sees while it holds `activation`,
/// per mA: the chord of R over kPidSlopeChordMa about the first amplitude
/// in [lo, hi] that recruits it (hi if none does), within [lo, hi].
/// @throws std::invalid_argument unless lo < hi, all finite.
double PidRecruitmentSlope(const PiecewiseLinear& irc, double lo, double hi, double activation);

LoopShape LoopShapeOf(const ParameterSet& params, const KneeTarget& target,
                      const TrackingOptions& options,
                      std::optional<double> about_deg = std::nullopt);

/// The open loop C(jω)·P(jω) with kp = 1.
std::complex<double> UnitLoop(const LoopShape& loop, double omega);

/// The lowest frequency (rad/s, 0.05–500) where the unit loop's phase
/// reaches −180°, if it does.
std::optional<double> PhaseCrossover(const LoopShape& loop);

/// The PID gains a tracking run uses when none are given: kp for a gain
/// margin of kGainMargin at the phase crossover of LoopShapeOf (classical
/// loop shaping on the set's linearised leg) about the target's mean angle,
/// its most extended and its most flexed angle, the smallest of the three
/// (the margin holds wherever the target takes the knee: the leg's local
/// stiffness and damping change along it), at most a static loop gain
/// kp·plant_gain/K of 1 (`pid`) or 2 (around the compensator); `pid`:
/// integral_s 1 s, derivative_s 0.1 s; around the compensator 0.5 s and
/// 0.03 s. (Fixed loop gains fail both ways: on the example set a torque
/// kp = K_θ diverges with the model itself as the plant, while on the
/// simulated cohort kp = 0.25·K_θ leaves 3–4° of hysteresis and friction.)
/// @throws std::invalid_argument as InvertModel.
Pid::Gains TuneGains(const ParameterSet& params, const KneeTarget& target,
                     const TrackingOptions& options);

/// Bounds of a tracking run's slew limit, mA/s.
inline constexpr double kMinSlewLimitMaPerS = 5.0;
inline constexpr double kMaxSlewLimitMaPerS = 5000.0;

/// The slew limit a loop can use, mA/s (docs/MODEL.md, "Tracking: the slew
/// limit"): ω₁₈₀·span_ma/2, with ω₁₈₀ the loop's phase crossover
/// (PhaseCrossover; 1/delay_s if the phase never reaches −180°) and span_ma
/// the amplitudes the loop recruits over (threshold to maximum). The
/// fastest command the loop can use is a swing over the whole span at
/// ω₁₈₀, where TuneGains sets the gain margin; its peak rate is
/// ω₁₈₀·span/2. Every command inside the span at or below ω₁₈₀ then passes
/// the limit untouched, so the limit adds no phase lag where the margin is
/// computed (a rate limiter that acts adds lag, and lag at ω₁₈₀ eats the
/// margin), and it cuts only what the loop cannot follow: steps, the
/// derivative's kicks, swings above the crossover. Clamped to 5–5000 mA/s
/// (the `tracking` protocol's bounds of max_rate_ma_per_s).
double SlewLimitFor(const LoopShape& loop, double span_ma);

/// SlewLimitFor(LoopShapeOf(params, target, options), max − threshold): the
/// default slew limit of a tracking run with a set.
/// @throws std::invalid_argument as LoopShapeOf.
double DefaultSlewLimit(const ParameterSet& params, const KneeTarget& target,
                        const TrackingOptions& options);

/// The most extended knee angle, deg, at which the set predicts the knee is
/// held still with at most activation_fraction of the activation the
/// maximum amplitude recruits, R(max_amplitude_ma) (Eqs. 3.16–3.20 at rest:
/// f·τ_scale·f_ata(θ)·f_atv(0) = −τ_pta(θ)): from the passive rest angle
/// (model::FindPassiveRestAngle; 90° without one) toward extension in steps
/// of 0.1°, the last angle before the needed activation exceeds that bound
/// (down to 0°). The quadriceps only extends, so flexion up to the rest
/// angle needs no stimulation. `tracking` fits its default target to it
/// (docs/PROTOCOLS.md, tracking).
/// @throws std::invalid_argument for an invalid set, a negative amplitude
///   or a fraction outside (0, 1].
double ReachableExtensionDeg(const ParameterSet& params, double max_amplitude_ma,
                             double activation_fraction = 1.0);

/// An uploaded trajectory (t_s, angle_deg) resampled at rate_hz by linear
/// interpolation from its t = 0 (its first time) to its last.
/// @throws std::invalid_argument (the message names the sample) for fewer
///   than 3 samples, lengths that differ, a non-finite value, times not
///   strictly increasing, or rate_hz ≤ 0.
std::vector<double> ResampleTarget(const std::vector<double>& t_s,
                                   const std::vector<double>& angle_deg, double rate_hz);

/// `target` preceded by a lead-in: a raised-cosine move from from_deg to the
/// target's first angle lasting lead_in_s (zero velocity at both ends),
/// derivatives exact, at the target's rate.
/// @throws std::invalid_argument for an empty target, a non-finite from_deg
///   or lead_in_s < 0.
KneeTarget WithLeadIn(const KneeTarget& target, double from_deg, double lead_in_s);

/// How well a knee angle followed a target (both sampled at the target's
/// rate from its t = 0; the shorter length counts).
struct TrackingMetrics {
  double rms_deg = 0.0;        ///< RMS of θ − θ*.
  double max_error_deg = 0.0;  ///< largest |θ − θ*|.
  /// Holds only (a target with plateaus after moves; unset otherwise): the
  /// median over the holds of the largest excursion past the hold angle in
  /// the direction of the move that led to it, deg (0 if none) ...
  std::optional<double> overshoot_deg;
  /// ... and of the time from the move's end until |θ − θ*| stays within
  /// settle_band_deg for the rest of the hold (the hold's length if never).
  std::optional<double> settling_s;
  /// The same two figures of the worst hold (a median hides one hold that
  /// oscillates).
  std::optional<double> worst_overshoot_deg;
  std::optional<double> worst_settling_s;
  /// RMS of the part of θ − θ* above 1 Hz, deg (Parseval over the error's
  /// DFT, Eigen's FFT): what oscillates faster than any target the
  /// protocol draws (0 when fewer than 2 s of samples).
  double rms_above_1hz_deg = 0.0;
};

/// @throws std::invalid_argument for an empty overlap or settle_band ≤ 0.
TrackingMetrics MeasureTracking(const KneeTarget& target, const std::vector<double>& angle_deg,
                                double settle_band_deg = 2.0);

/// A limit cycle of the tracking loop, seen online in the error θ − θ*
/// (beyond the thesis; docs/MODEL.md, "Tracking: oscillation back-off"): a
/// half-cycle is the stretch between two sign changes of the error (with
/// a hysteresis of hysteresis_deg); `half_cycles` half-cycles in a row that
/// each reach peak_deg, last at most max_half_period_s and reach at least
/// `sustain` times the peak of the half-cycle before the last (the same
/// sign: an oscillation about an offset counts) are an oscillation. A
/// swing that dies out faster (ζ above about 0.06) is a loop settling. The targets the protocol
/// draws move at 0.2 Hz or slower (a half-period of 2.5 s), so a tracking lag swings too slowly to
/// count, while a loop with too much gain for its delay swings at 0.5–3 Hz.
class OscillationDetector {
 public:
  struct Options {
    double peak_deg = 4.0;
    double max_half_period_s = 1.5;
    int half_cycles = 4;
    double hysteresis_deg = 0.5;
    double sustain = 0.7;
  };
  /// @throws std::invalid_argument for rate_hz ≤ 0 or options that are not
  ///   finite and > 0 (hysteresis < peak, half_cycles ≥ 2, sustain ≤ 1).
  OscillationDetector(double rate_hz, Options options);
  /// One sample of the error; true at the sample that completes an
  /// oscillation (the count then starts again).
  bool Update(double error_deg);

 private:
  Options options_;
  double dt_s_;
  int sign_ = 0;           // the current half-cycle's sign (0: none yet)
  double peak_deg_ = 0.0;  // its largest |error|
  double length_s_ = 0.0;  // its length so far
  int count_ = 0;          // qualifying half-cycles in a row
  // The peaks of the last two half-cycles (0: none since the last start).
  double previous_peak_deg_ = 0.0, before_previous_peak_deg_ = 0.0;
};

/// Back-offs of the loop gain a tracking controller takes before it gives
/// up: each halves kp, ki and kd (OscillationDetector).
inline constexpr int kMaxOscillationBackoffs = 3;

struct TrackingSample;

/// The back-off every controller takes (TrackingController, and the
/// engine's model-free PID): the sample's error goes to `detector`; when it
/// completes an oscillation, `pid`'s gains are halved (backoffs + 1,
/// sample.backed_off) or, after kMaxOscillationBackoffs, sample.oscillating
/// is set. The next samples use the halved gains.
void BackOffOnOscillation(OscillationDetector& detector, Pid& pid, int& backoffs,
                          TrackingSample& sample);

/// What one control sample decided.
struct TrackingSample {
  double amplitude_ma = 0.0;    ///< commanded, in [0, max_amplitude_ma].
  double target_deg = 0.0;      ///< θ* at this sample.
  double error_deg = 0.0;       ///< θ − θ* (positive: too flexed).
  double feedforward_ma = 0.0;  ///< the model's amplitude (pid: the threshold bias).
  double correction_ma = 0.0;   ///< amplitude − feedforward.
  double tau_scale_nm = 0.0;    ///< τ̂_scale (the set's value unless adaptive).
  /// The output is held at the maximum amplitude (or, around the model, at
  /// the set's full recruitment) while the knee is too flexed: the
  /// controller asks for more than it may give.
  bool saturated = false;
  /// This sample completed an oscillation (OscillationDetector) and the
  /// controller halved its gains ...
  bool backed_off = false;
  /// ... or it had done so kMaxOscillationBackoffs times already: the run
  /// must end.
  bool oscillating = false;
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
  /// The gains the run started with (before any back-off).
  const Pid::Gains& gains() const { return gains_; }
  /// The gains now: gains() halved once per back-off.
  const Pid::Gains& current_gains() const { return pid_.gains(); }
  int backoffs() const { return backoffs_; }
  /// τ̂_scale now: ĝ·τ_scale·s(t) (adaptive; the set's τ_scale otherwise).
  double tau_scale_nm() const { return tau_scale_; }
  /// The strength state's prediction s(t) (1 without a strength state).
  double strength() const { return StrengthFactor(strength_); }

 private:
  // f_stim* the target needs a lead n/a after sample i, with the current τ̂.
  double FeedforwardActivation(std::size_t i) const;
  double AmplitudeFor(double activation) const;  // R⁻¹, capped
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
  // The estimator's τ̂ of g·τ_scale, clamped (tau_scale_ is it times s).
  double base_scale_;
  ScaleEstimator estimator_;
  std::optional<StrengthModel> strength_model_;
  StrengthState strength_{};
  // Measured-motion filter (θ_f, θ̇_f in deg, deg/s) and the same filter on
  // the regression's model side: passive torque and φ.
  std::array<double, 2> angle_filter_{};
  std::array<double, 2> passive_filter_{};
  std::array<double, 2> regressor_filter_{};
  bool filters_started_ = false;
  ContractionPropagator chain_;
  ContractionState activation_{};
  std::int64_t next_pulse_ = 0;  // index of the next pulse-clock tick
  OscillationDetector oscillation_;
  int backoffs_ = 0;
};

}  // namespace fesbench::model
