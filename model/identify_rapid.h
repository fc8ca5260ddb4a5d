#pragma once

/// @file
/// Rapid parameterisation (thesis §7.4.1): a complete parameter set from
/// three short trials —
///  1. an isometric ramp trial (impulses + cosine ramp, knee locked): the
///     contraction pole from the averaged impulse responses (Eqs. 4.2, 4.4)
///     and the IRC by deconvolving the ramp's torque with the contraction
///     dynamics just identified (Eqs. 4.6–4.8; beyond the thesis, which
///     used ramp correlation, Eq. 4.5: docs/MODEL.md, "The rapid routine's
///     IRC");
///  2. a free-swing trial under a sparse random-binary train and
///  3. a free-swing trial under a dense random-binary train:
///     with the limb inertia J known ("the torque-angle curve can be
///     estimated from the free swing method if the inertia is already
///     known", §7.4.1), τ_pta(θ) and τ_ptv(θ̇) from the passive samples
///     (f_stim ≤ 0.01) of both, by Eq. 4.35 with J moved to the left:
///       −J·θ̈ = Σ c_j X_j(θ) + Σ c_k X_k(θ̇)   (Eq. 4.30 basis, SVD Eqs. 4.19–4.26),
///     then f_ata, f_atv and τ_scale from the stimulated samples (f_stim ≥
///     0.01) by Eq. 4.40;
///  4. (beyond the thesis) the linear estimates of step 3 refined by
///     output error: Levenberg–Marquardt on the knee-angle error of the
///     model simulated through both recorded free-swing trials (E_RMS,
///     Eq. 6.9, the measure §6.9 judges prediction by), pulled toward the
///     linear estimates (RefineOutputError). The equation-error fits weigh
///     torque residuals that the leg's unmodelled effects (series
///     elasticity, hysteresis, friction, potentiation, §3.3, §6.6) bias;
///     the refinement trades them for the angles themselves.
/// Velocity and acceleration come from the position by a GCV smoothing
/// spline (§5.1, and §7.4.1: "the position signal could be double
/// differentiated off-line … This would eliminate the need to calibrate
/// the accelerometer"); f_stim from the identified IRC and contraction
/// dynamics driven by the recorded envelope's pulses.

#include <optional>

#include "model/identify_active.h"
#include "model/identify_common.h"
#include "model/identify_isometric.h"
#include "model/identify_passive.h"
#include "model/parameter_set.h"
#include "model/signal.h"
#include "model/simulate.h"

namespace fesbench::model {

/// How the rapid routine identifies the IRC: the ramp deconvolved by the
/// contraction dynamics identified from the same trial's impulses.
inline constexpr IrcMethod kRapidIrcMethod = IrcMethod::kRampDeconvolutionIdeal;

/// Options of IdentifyRapid.
struct RapidOptions {
  double inertia_kgm2 = 0.0;            ///< known limb inertia J > 0, kg·m².
  double pulse_rate_hz = 33.0;          ///< stimulator pulse rate, Hz (> 0).
  /// Order 3, pole by least squares on the whole averaged twitch (the peak
  /// time alone is 2–7 % off on the cohort, the whole shape −2.7…−4.5 %:
  /// docs/MODEL.md).
  ContractionOptions contraction{TwitchOptions{}, 3, PoleMethod::kLeastSquares};
  /// Ramp-deconvolution settings (`ideal` is replaced by the identified
  /// contraction).
  IrcOptions irc{};
  /// The session's threshold, mA (the tolerance test's first response,
  /// §5.2.1): the IRC's onset is put there (WithOnsetAtThreshold). Unset:
  /// the deconvolved curve as it is, toe and all.
  std::optional<double> threshold_ma;
  BreakpointSpec passive_angle{9, {}};  ///< τ_pta breakpoints over the visited range.
  BreakpointSpec passive_velocity{7, {}};
  BreakpointSpec active_angle{7, {}};
  BreakpointSpec active_velocity{7, {}};
  double max_passive_activation = 0.01;  ///< §5.4.3.
  /// ActiveOptions::smoothness of the active fit.
  double active_smoothness = 0.02;
  double relative_tolerance = 1e-8;      ///< SVD truncation (Eq. 4.26).
  /// Output-error iterations after the linear fits (RefineOutputError);
  /// 0 keeps the thesis's linear estimates.
  int refine_iterations = 6;
  /// Weight of the pull toward the linear estimates (OutputErrorOptions).
  double refine_prior_weight = 0.01;
  /// The bench's stops (the subject's range of motion). When set, samples
  /// within stop_margin_deg of a stop, and stop_guard_s either side of them,
  /// are left out of the equation-error fits (the stop's contact torque is
  /// not in the model), and the output-error simulations stop there.
  std::optional<JointLimits> joint_limits;
  double stop_margin_deg = 2.0;
  double stop_guard_s = 0.1;
  /// Extrapolate every curve beyond the range it was identified over
  /// (model/extrapolate.h) out to extend_angle_deg (the stops ± 10° when
  /// joint_limits is set, else 0–130°) and ±extend_velocity_deg_s.
  bool extrapolate = true;
  double extend_velocity_deg_s = 1000.0;
  /// m·g·l of the shank, N·m, for the gravity term when the passive data
  /// span under 60° (0 = fit it; FitPassiveAngleForm).
  double mgl_prior_nm = 0.0;
  /// InertiaFromReleases's window: the first window_s of each released
  /// swing at most, s (0.16 s: shorter is noisier, longer lets the changing
  /// torque in; measured on the cohort, docs/MODEL.md) ...
  double release_window_s = 0.16;
  /// ... ended where the knee has travelled release_max_travel_deg from
  /// the release angle, but not before release_min_window_s (docs/MODEL.md,
  /// "J measured by the rapid routine").
  double release_max_travel_deg = 15.0;
  double release_min_window_s = 0.06;
  /// A J from the releases outside [1/max_inertia_scale, max_inertia_scale]
  /// of the given inertia is reported and not applied.
  double max_inertia_scale = 1.6;
};

/// The trials of one rapid run (§7.4.1 and beyond it).
struct RapidTrials {
  TrialColumns isometric;             ///< the isometric ramp trial (t_s, stim_ma, torque_nm).
  std::vector<TrialColumns> swings;   ///< free swings (t_s, stim_ma, angle_deg).
  /// Releases: the hold just before a release (t_s, angle_deg, torque_nm)
  /// and the index in `swings` of the free swing that starts at the
  /// release. With two or more, J is measured from them
  /// (InertiaFromReleases); else it stays options.inertia_kgm2.
  struct Release {
    TrialColumns hold;
    std::size_t swing = 0;
  };
  std::vector<Release> releases;
};

/// What InertiaFromReleases returns.
struct ReleaseInertia {
  double inertia_kgm2 = 0.0;
  std::vector<double> hold_torque_nm;   ///< per release.
  std::vector<double> accel_deg_s2;     ///< per release, at its first sample.
  std::vector<double> window_s;         ///< per release, the window fitted.
  double rms_nm = 0.0;                  ///< misfit of torque = c − J·θ̈₀.
};

/// J from the start of each release (beyond the thesis): at the instant the
/// motor lets go of the still knee, nothing but the held torque moves it,
/// J·θ̈₀ = −τ_hold (Eq. 4.9 with θ̇ = 0 and no brace torque; the tissue's
/// hysteresis is in the held torque and acts the same just after). θ̈₀ is
/// the t² term of a cubic fitted to the start of the swing's angle;
/// τ_hold the mean of the hold's second half. J is the least-squares slope
/// of τ_hold against −θ̈₀ over the releases (the intercept takes the torque
/// sensor's offset). Friction opposing the first motion biases J by about
/// 2·F/Δτ_hold (a few %).
///
/// The window is chosen by the angle travelled, not by time: it ends at the
/// first sample max_travel_deg from the first one, kept within
/// [min_window_s, window_s]. Once the knee moves, τ_pta(θ) (Eq. 4.9) is no
/// longer τ_hold: the cubic's t² term stays θ̈₀ while θ̈ changes about
/// linearly over the window, and the change grows with the travel and the
/// stiffness the knee runs through (steep end-range stiffness, Eq. 7.3,
/// turns a fixed window's t² term into an average over a falling torque).
/// Bounding the travel bounds that change; the noise of the t² term,
/// relative to θ̈₀, is set by the travel too (σ_θ / (θ̈₀·T²) ∝ σ_θ / travel),
/// so a leg that accelerates fast gets a short window and no noisier an
/// estimate. min_window_s keeps enough samples for the cubic.
/// @throws std::invalid_argument if fewer than 2 releases, a column is
///   missing, a swing is shorter than its window, or the held torques do
///   not differ.
ReleaseInertia InertiaFromReleases(std::span<const TrialColumns> swings,
                                   std::span<const RapidTrials::Release> releases,
                                   double window_s = 0.16, double max_travel_deg = 15.0,
                                   double min_window_s = 0.06);

/// The trial without the samples within margin_deg of a stop, and guard_s
/// either side of them: a stop's contact torque is not in the model.
TrialColumns WithoutStopContact(const TrialColumns& trial, const JointLimits& stops,
                                double margin_deg, double guard_s);

/// Every torque of a set times `scale`, J with them: τ_pta, τ_ptv ordinates,
/// τ_scale and inertia (the free-swing motion is unchanged, Eq. 4.35).
ParameterSet ScaleTorques(const ParameterSet& p, double scale);

/// Options of RefineOutputError.
struct OutputErrorOptions {
  int iterations = 6;           ///< Levenberg–Marquardt iterations (≥ 0).
  double pulse_rate_hz = 33.0;  ///< stimulator pulse rate, Hz (> 0).
  double step_s = 5e-3;         ///< RK4 step of the simulations, s (> 0).
  int stride = 2;               ///< every stride-th sample enters the error (≥ 1).
  /// Prior: each ordinate's distance from its start value, divided by its
  /// scale below, enters the cost with weight prior_weight·(number of angle
  /// samples), so a change of one scale costs as much as raising the mean
  /// squared angle error by prior_weight deg² (≥ 0; 0 = no prior).
  double prior_weight = 0.01;
  double passive_torque_scale_nm = 0.5;  ///< τ_pta and τ_ptv ordinates.
  double passive_velocity_scale_nm = 0.3;
  double active_gain_scale = 0.2;           ///< f_ata and f_atv ordinates.
  double log_torque_scale = 0.2;            ///< ln τ_scale.
  std::optional<JointLimits> joint_limits;  ///< stops of the simulations.
};

/// What RefineOutputError returns: the refined set (passive referenced,
/// active normalised) and fit_rms "output_error_start_deg" /
/// "output_error_deg" (knee-angle RMS over the trials before and after),
/// values "output_error_iterations".
struct OutputErrorResult {
  ParameterSet parameters;
  IdentifyReport report;
};

/// Refines τ_pta, τ_ptv, f_ata, f_atv (ordinates at their breakpoints) and
/// τ_scale of a full-model set by Levenberg–Marquardt on the knee angle
/// simulated in free swing (SimulateFreeSwing, muscle at rest at each
/// trial's start, θ and θ̇ from its first sample) against each trial's
/// angle_deg, with a Tikhonov pull toward `start`. Inertia, IRC and
/// contraction dynamics are kept. Trials need t_s, stim_ma, angle_deg and
/// velocity_deg_s. A step is taken only if it lowers the cost (a diverging
/// simulation counts as no improvement), so the result is never worse on
/// the trials than `start`.
/// @throws std::invalid_argument if there are no trials, a column is
///   missing, start has empty curves, or an option is out of range.
OutputErrorResult RefineOutputError(const ParameterSet& start, std::span<const TrialColumns> trials,
                                    const OutputErrorOptions& options = {});

/// A parameter set and what the fits reported.
struct RapidResult {
  ParameterSet parameters;
  IdentifyReport report;
};

/// The whole §7.4.1 identification. `isometric` needs t_s, stim_ma,
/// torque_nm (offset-corrected or not); `passive` and `active` need t_s,
/// stim_ma and angle_deg (velocity, acceleration and activation are
/// computed). Provenance: irc_method "ramp_deconvolution_ideal", passive_method
/// "free_swing_known_inertia", active_method "log_least_squares"; with
/// refine_iterations > 0 the passive and active curves are then refined
/// by RefineOutputError on both free-swing trials (fit_rms
/// "output_error_deg").
/// @throws std::invalid_argument if inertia_kgm2 is not > 0 or any fit's
///   precondition fails (the message names it).
RapidResult IdentifyRapid(const TrialColumns& isometric, const TrialColumns& passive,
                          const TrialColumns& active, const RapidOptions& options);

/// The same from any number of free-swing trials (each needs t_s, stim_ma,
/// angle_deg): passive samples of all of them give τ_pta, τ_ptv, stimulated
/// samples f_ata, f_atv, τ_scale; the refinement runs on all of them. With
/// options.extrapolate the curves are extended beyond their data
/// (model/extrapolate.h) and provenance.identified_range_deg /
/// identified_range_deg_s record the ranges of the data ("tau_pta",
/// "f_ata"; "tau_ptv", "f_atv").
/// @throws std::invalid_argument as above, or if `swings` is empty.
RapidResult IdentifyRapid(const TrialColumns& isometric, std::span<const TrialColumns> swings,
                          const RapidOptions& options);

/// The same, and with releases (RapidTrials::releases) J is then measured:
/// the swings fix every torque only relative to J (scaling J and every
/// torque by one factor leaves Eq. 4.35's motion unchanged), so the set
/// identified with options.inertia_kgm2 is scaled by ScaleTorques to the J
/// of InertiaFromReleases (report value "inertia_release_kgm2", fit_rms
/// "inertia_releases_nm"; provenance.inertia_method "releases"). A J outside
/// the allowed factor, or releases that cannot give one, leave J as given
/// with a warning naming why.
RapidResult IdentifyRapid(const RapidTrials& trials, const RapidOptions& options);

}  // namespace fesbench::model
