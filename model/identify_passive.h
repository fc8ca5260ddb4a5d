#pragma once

/// @file
/// Passive identification (thesis §4.2, §5.4.1–5.4.3, §6.5–6.6): the
/// sequential method (static holds, constant-velocity moves, anthropometric
/// inertia), simultaneous linear estimation (Eq. 4.31) and free swing
/// (Eq. 4.35). Every result is referenced as in §6.5 (ReferencePassive:
/// τ_pta(90°) = 0, the constant moved into τ_ptv), so τ_pta + τ_ptv is
/// unchanged.
///
/// Motor-mode trials need t_s, angle_deg, velocity_deg_s, accel_deg_s2 and
/// torque_nm (the torque the brace applies, Eq. 4.9); free-swing trials
/// need t_s, angle_deg, velocity_deg_s, accel_deg_s2 and activation
/// (f_stim, e.g. from ActivationAt). Acceleration is in deg/s² and is
/// converted to rad/s² for the inertia term.

#include <array>
#include <optional>
#include <span>
#include <string_view>

#include "model/conditioning.h"
#include "model/identify_common.h"
#include "model/parameter_set.h"
#include "model/simulate.h"

namespace fesbench::model {

/// A passive parameter set with its report.
struct PassiveResult {
  PassiveParams passive;
  IdentifyReport report;
};

/// The three passive identifications of §4.2: sequential (§4.2.1),
/// simultaneous (§4.2.2), free swing (§4.2.3).
enum class PassiveMethod { kSequential, kSimultaneous, kFreeSwing };
/// Every passive method, in declaration order.
inline constexpr std::array<PassiveMethod, 3> kPassiveMethods = {
    PassiveMethod::kSequential, PassiveMethod::kSimultaneous, PassiveMethod::kFreeSwing};

/// "sequential", "simultaneous", "free_swing".
std::string_view PassiveMethodName(PassiveMethod method);
/// The method called `name` (PassiveMethodName's words), or nullopt.
std::optional<PassiveMethod> PassiveMethodFromName(std::string_view name);

/// Eq. 4.13, §4.2.1: J = (0.061·w)·(0.735·l)², w body mass in kg, l the
/// femoral condyle to medial malleolus length in m.
/// @throws std::invalid_argument unless both are finite and > 0.
double AnthropometricInertia(double body_mass_kg, double leg_length_m);

/// The shank-and-foot gravity moment m·g·l, N·m, with Eq. 4.13's mass
/// fraction 0.061 and the segment's centre of mass at 0.606 of its length
/// (Winter, Table 4.1): the amplitude of the gravity term of Eq. 7.3.
/// @throws std::invalid_argument unless both are finite and > 0.
double AnthropometricGravityMoment(double body_mass_kg, double leg_length_m);

/// Options of the sequential method.
struct SequentialPassiveOptions {
  HoldOptions holds;                          ///< hold detection, 50-sample means.
  double hold_tolerance_deg = 0.5;            ///< holds this close are one angle.
  double constant_velocity_tolerance = 0.03;  ///< |θ̇| within 3 % of the move's peak.
  double min_move_speed_deg_s = 1.0;          ///< slower samples are not moving.
  double use_last_s = 1.0;                    ///< §5.4.1: last 1 s of each move.
  std::optional<double> body_mass_kg;         ///< with leg_length_m: Eq. 4.13.
  std::optional<double> leg_length_m;
  double inertia_kgm2 = 0.36;  ///< used when mass/length are absent.
};

/// Sequential identification (§4.2.1, §5.4.1): τ_pta from the position
/// holds of `positions` averaged over both directions (Eq. 4.10); τ_ptv
/// from the constant-velocity part of each move of `velocities`, τ_pta
/// removed (Eq. 4.12) and averaged over its last use_last_s, with τ_ptv(0)
/// = 0 (the holds define zero velocity); J from Eq. 4.13.
/// @throws std::invalid_argument if a needed column is missing, no hold or
///   no move is found.
PassiveResult IdentifyPassiveSequential(const TrialColumns& positions,
                                        const TrialColumns& velocities,
                                        const SequentialPassiveOptions& options = {});

/// Options of the simultaneous least-squares method.
struct SimultaneousPassiveOptions {
  BreakpointSpec angle{11, {}};       ///< τ_pta breakpoints (§7.4.4: 11).
  BreakpointSpec velocity{9, {}};     ///< τ_ptv breakpoints.
  double relative_tolerance = 1e-10;  ///< SVD truncation (Eq. 4.26).
  double min_support = 1.0;           ///< breakpoint support warning, samples.
  double coverage_warn_below = 0.25;
  /// Samples with activation above this are not passive (as in the
  /// free-swing fit's options).
  double max_activation = 0.01;
};

/// Simultaneous linear estimation (§4.2.2, Eq. 4.31): τ_motor = Σ c_j·X_j(θ)
/// + Σ c_k·X_k(θ̇) + J·θ̈, solved by truncated SVD (Eqs. 4.19–4.26) over all
/// samples of all trials (samples with activation > max_activation are
/// skipped when an activation column is present).
/// @throws std::invalid_argument on missing columns or too few samples.
PassiveResult IdentifyPassiveSimultaneous(std::span<const TrialColumns> trials,
                                          const SimultaneousPassiveOptions& options = {});

/// Options of the free-swing method.
struct FreeSwingPassiveOptions {
  BreakpointSpec velocity{4, {}};  ///< τ_ptv breakpoints (§7.4.4: 4).
  double max_activation = 0.01;    ///< §5.4.3: passive samples only.
  double relative_tolerance = 1e-10;
  double min_support = 1.0;
  /// J by output error (beyond the thesis): Eq. 4.35's least squares puts
  /// the noisy θ̈ among the regressors, which attenuates J (errors in
  /// variables: −29…−97 % on the virtual cohort). With this set, J is
  /// instead the value whose free swing, simulated through every passive
  /// stretch of at least min_segment_s (split at max_segment_s) from its
  /// measured first state, best matches the measured knee angle, τ_ptv
  /// refitted by Eq. 4.35 with that J fixed (θ̈ then only on the left).
  bool output_error_inertia = true;
  double min_segment_s = 0.4;
  double max_segment_s = 2.0;
  /// A stretch ends once the rest of it spans less than this, and stretches
  /// spanning less are left out: in a small oscillation the tissue's
  /// hysteresis (Fig. 3-7) acts as an extra spring the model does not have,
  /// and J fitted there comes out low (−29 % and −31 % on two legs of the
  /// cohort with every stretch, −1…−7 % with this). If no stretch spans it,
  /// ¾, ½, ¼ of it and then every stretch are tried, deg (0 = keep all;
  /// report value "free_swing_segment_excursion_deg" is the one used).
  double min_segment_excursion_deg = 20.0;
  /// Stretches are cut where the knee comes within stop_margin_deg of a
  /// stop (contact torque is not in the model); unset = no stops.
  std::optional<JointLimits> joint_limits;
  double stop_margin_deg = 3.0;
  /// Stretches start once the activation is below this (the muscle's
  /// residual pull after a burst biases J more than the fit's samples).
  double segment_max_activation = 0.001;
  double min_inertia_kgm2 = 0.05;  ///< search bracket of J, kg·m².
  double max_inertia_kgm2 = 3.0;
};

/// Free-swing identification (§4.2.3, Eq. 4.35): with τ_pta known (from the
/// sequential method), −τ_pta(θ) = Σ c_k·X_k(θ̇) + J·θ̈ on the samples with
/// activation ≤ max_activation; with output_error_inertia J by output error
/// (report values "free_swing_inertia_equation_error_kgm2" and
/// "free_swing_inertia_segments", fit_rms "free_swing_output_error_deg").
/// @throws std::invalid_argument on missing columns, an empty τ_pta or too
///   few passive samples.
PassiveResult IdentifyPassiveFreeSwing(std::span<const TrialColumns> trials,
                                       const PiecewiseLinear& torque_angle,
                                       const FreeSwingPassiveOptions& options = {});

/// τ_pta and τ_ptv from free-swing trials with known inertia (§7.4.1,
/// Eq. 4.35 rearranged): uses the samples with activation ≤
/// max_activation. Trials need t_s, angle_deg, velocity_deg_s,
/// accel_deg_s2, activation. Result referenced (§6.5, ReferencePassive).
/// @throws std::invalid_argument if inertia_kgm2 is not > 0, a column is
///   missing, or there are fewer passive samples than parameters.
PassiveResult IdentifyPassiveKnownInertia(std::span<const TrialColumns> trials, double inertia_kgm2,
                                          const BreakpointSpec& angle = {9, {}},
                                          const BreakpointSpec& velocity = {7, {}},
                                          double max_activation = 0.01,
                                          double relative_tolerance = 1e-8);

}  // namespace fesbench::model
