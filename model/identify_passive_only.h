#pragma once

/// @file
/// Passive-only identification (beyond the thesis's routines, built from
/// its parts): τ_pta and τ_ptv of a knee from free swings without
/// stimulation, such as the pendulum (Wartenberg) test, where the shank is
/// released from extension and swings to rest. The thesis identifies the
/// passive block from free swings with τ_pta known (§4.2.3, Eq. 4.35) or
/// with J known (§7.4.1); a pendulum recording brings neither a torque
/// sensor nor an isometric trial, and Eq. 4.35 is homogeneous in J and the
/// torques: the kinematics fix every torque only relative to J. The scale
/// comes from outside, either J itself (given) or the gravity moment m·g·l
/// of the shank (the subject's anthropometrics, or a lab's scaled model):
/// with gravity's amplitude fixed, the swing's period gives J
/// (EstimatePendulumInertia).
///
/// Steps (docs/MODEL.md "Passive-only identification"):
///   0. each trial from its release on (PendulumReleaseIndex);
///   1. θ̇ and θ̈ by the GCV smoothing spline (§5.1) where not recorded;
///   1a. J, unless given, from the swings with m·g·l fixed
///      (EstimatePendulumInertia);
///   2. Eq. 4.35 rearranged with J known, over every sample away from a
///      bench's stops (IdentifyPassiveKnownInertia): −J·θ̈ = τ_pta(θ) + τ_ptv(θ̇);
///   3. τ_pta continued beyond the angles the swings visited by the Eq. 7.3
///      form with end-range stiffness (model/extrapolate.h), τ_ptv by its
///      edge segments; referenced as in §6.5;
///   4. τ_pta and τ_ptv refined by output error on the knee angle
///      (RefineOutputError, the rapid routine's refinement): the swing
///      simulated from each trial's first state matches the recording.
/// The result is a parameter set whose IRC maps every current to zero
/// activation and whose provenance says "none" for the IRC and active
/// methods (IsPassiveOnly): it predicts unstimulated swings and nothing
/// else.

#include <optional>
#include <span>

#include "model/identify_common.h"
#include "model/parameter_set.h"
#include "model/simulate.h"

namespace fesbench::model {

/// The provenance word of the blocks a passive-only set does not have.
inline constexpr const char* kNotIdentified = "none";

/// True if `params` was identified without stimulation (provenance
/// irc_method or active_method "none"): its IRC and active curves are
/// placeholders and it must not predict or drive stimulation.
bool IsPassiveOnly(const ParameterSet& params);

/// The sample from which a pendulum test's knee swings freely. A trial
/// that begins with a hold — the knee within hold_deg of its first angle
/// for at least min_hold_s, the examiner holding the shank — is taken up at
/// the first sample more than departure_deg from the first one: the hand
/// lets go over a few samples, a torque the model does not have (on a real
/// recording, starting at the first movement instead left 12–14° of error
/// on a held-out swing, starting here 5–6°, docs/MODEL.md); the swing is
/// taken up there with its measured velocity. 0 for a trial that moves
/// from its start (released as it begins, as the bench records) or never
/// departs.
/// @throws std::invalid_argument if the spans differ in length.
std::size_t PendulumReleaseIndex(std::span<const double> t_s, std::span<const double> angle_deg,
                                 double departure_deg = 2.0, double hold_deg = 0.5,
                                 double min_hold_s = 0.2);

/// The trial from sample `from` on (every column with one value per
/// sample; times kept as they are).
TrialColumns TrialFromSample(const TrialColumns& trial, std::size_t from);

/// Marks `params` passive-only (IsPassiveOnly): active method kNotIdentified
/// and, unless the IRC was identified, an IRC that activates nothing with
/// its method kNotIdentified. The other blocks are left as they are.
void MarkPassiveOnly(ParameterSet& params, bool irc_identified);

/// J of a freely swinging shank with its gravity moment known (beyond the
/// thesis, from its parts): Eq. 4.35, −J·θ̈ = τ_pta(θ) + τ_ptv(θ̇), with
/// the parametric τ_pta of §7.4.4 (Eq. 7.3, the form of model/extrapolate.h)
/// whose gravity amplitude is m·g·l:
///   τ_pta = m·g·l·sin(θ − θ_h) + c − k_e·e^(−(θ − lo)/w_e) + k_f·e^((θ − hi)/w_f),
///   τ_ptv = b₊·max(θ̇, 0) + b₋·min(θ̇, 0) + d·tanh(θ̇ / 5 deg/s),
/// lo and hi the angles visited, fitted by output error: each stretch of a
/// swing simulated (RK4) from its first recorded state, the knee angle
/// matched by Levenberg–Marquardt over J, θ_h, c, k_e, w_e, k_f, w_f, b₊,
/// b₋, d, starting from a pendulum hanging where the swing comes to rest
/// with the period of its turning points (J = m·g·l/ω²); the widths are
/// held within 2–20° (wider, an end term acts as mid-range stiffness and
/// trades with θ_h). With gravity's
/// amplitude fixed, gravity's stiffness m·g·l·cos(θ − θ_h) cannot take J's
/// scale, and the period of the mid-range swing gives J; stiffness the
/// tissue adds mid-range is read as gravity's, so J comes out low by its
/// share (docs/MODEL.md). Whether the swings determine J at all is read off
/// J's profile: the fit repeated with J held kProfileFactor below and
/// above the best, everything else refitted; J is determined when both
/// leave an output error at least kDeterminedRmsRatio times the best's. On
/// the bench's legs (tissue stiffness reaching mid-range, swings over
/// 13–98°) the profile is flat — J ×0.5…×1.4 fit within 5 % — and J is not
/// determined; a knee whose tissue acts only near the ends is. An
/// equation-error fit of the same form was tried
/// first and refused: the spline's θ̈ (§5.1) is noisy where the tissue
/// stiffens, and the least squares then preferred a J near 0 with the end
/// terms cancelling gravity.
inline constexpr double kProfileFactor = 1.25;
inline constexpr double kDeterminedRmsRatio = 1.25;

struct PendulumInertia {
  double inertia_kgm2 = 0.0;  ///< J, kg·m².
  /// Output error with J held at J / kProfileFactor and J·kProfileFactor.
  double profile_rms_low_deg = 0.0, profile_rms_high_deg = 0.0;
  bool determined = false;  ///< both ≥ kDeterminedRmsRatio·rms_deg.
  double hang_deg = 0.0;    ///< θ_h, where gravity's moment vanishes.
  double offset_nm = 0.0;   ///< c.
  double rms_deg = 0.0;     ///< output error of the fit, deg.
  std::size_t samples = 0;
};

/// EstimatePendulumInertia over `swings` (t_s, angle_deg, velocity_deg_s;
/// unstimulated, each from its release; a gap in t_s — a stop's contact
/// left out — splits a swing into stretches, those under 0.5 s unused).
/// @throws std::invalid_argument if gravity_moment_nm is not finite and
///   > 0, a column is missing, the swings span under 20° or never turn
///   back, or the fit hangs the shank outside 0…180° (a swing recorded
///   flexion-negative).
PendulumInertia EstimatePendulumInertia(std::span<const TrialColumns> swings,
                                        double gravity_moment_nm);

/// Options of IdentifyPassiveOnly.
struct PassiveOnlyOptions {
  /// J, kg·m² (> 0), given; 0 = estimated from the swings with
  /// gravity_moment_nm (EstimatePendulumInertia).
  double inertia_kgm2 = 0.0;
  /// m·g·l of the shank, N·m (> 0; 0 = unknown): the scale of J when it is
  /// not given, and the gravity term of the extrapolation when the swings
  /// span under 60° (FitPassiveAngleForm).
  double gravity_moment_nm = 0.0;
  /// J, kg·m², taken when the swings do not determine it
  /// (PendulumInertia::determined; e.g. Eq. 4.13's); 0 = refuse then.
  double fallback_inertia_kgm2 = 0.0;
  /// τ_pta and τ_ptv breakpoints over the visited angles and speeds. On a
  /// real recording (docs/VALIDATION.md) 9 and 5 predicted the held-out
  /// swing best of 9/15 × 5/9; 9 velocity breakpoints made one fit unstable.
  BreakpointSpec angle{9, {}};
  BreakpointSpec velocity{5, {}};
  double relative_tolerance = 1e-8;       ///< SVD truncation (Eq. 4.26).
  double extend_angle_deg = 20.0;         ///< τ_pta continued this far beyond the data.
  double extend_velocity_deg_s = 1000.0;  ///< τ_ptv continued to ± this.
  int refine_iterations = 6;              ///< output-error iterations (0 = linear fit only).
  double refine_prior_weight = 0.01;      ///< OutputErrorOptions::prior_weight.
  /// A bench's stops (its range of motion); unset for recordings from
  /// elsewhere. When set, samples within stop_margin_deg of a stop, and
  /// stop_guard_s either side, are left out of step 2 (the stop's contact
  /// absorbs energy the tissue would be credited with: on the bench's
  /// cohort the damping came out 2–9 times the truth with them), and the
  /// refinement's simulations stop there.
  std::optional<JointLimits> joint_limits;
  double stop_margin_deg = 2.0;
  double stop_guard_s = 0.1;
};

/// What IdentifyPassiveOnly returns: the set (model kFull, IRC zero, default
/// contraction and active curves, provenance irc_method and active_method
/// kNotIdentified, passive_method "free_swing_known_inertia") and the
/// report (fit_rms "free_swing_known_inertia_nm", "tau_pta_form_nm",
/// "output_error_start_deg", "output_error_deg"; values
/// "passive_only_samples"; with J estimated also fit_rms
/// "pendulum_inertia_deg", values "pendulum_inertia_kgm2",
/// "pendulum_hang_deg", "pendulum_profile_low_deg",
/// "pendulum_profile_high_deg" and "pendulum_inertia_determined" (1 or 0),
/// and a warning when the fallback J was taken).
/// Where IdentifyPassiveOnly's J came from.
enum class InertiaSource {
  kGiven,     ///< options.inertia_kgm2.
  kSwings,    ///< EstimatePendulumInertia, determined.
  kFallback,  ///< options.fallback_inertia_kgm2 (the swings did not determine J).
};

struct PassiveOnlyResult {
  ParameterSet parameters;
  IdentifyReport report;
  InertiaSource inertia_source = InertiaSource::kGiven;
};

/// Identifies the passive block from unstimulated free swings, each from
/// its release (PendulumReleaseIndex) on. Each trial needs t_s and
/// angle_deg (velocity_deg_s and accel_deg_s2 are derived when missing);
/// stim_ma, when present, must be zero throughout.
/// @throws std::invalid_argument if there are no trials, neither
///   inertia_kgm2 nor gravity_moment_nm is finite and > 0, a trial is
///   stimulated, J is to be estimated and the swings do not determine it
///   with no fallback_inertia_kgm2, a column is missing or
///   there are fewer samples than parameters.
PassiveOnlyResult IdentifyPassiveOnly(std::span<const TrialColumns> trials,
                                      const PassiveOnlyOptions& options);

}  // namespace fesbench::model
