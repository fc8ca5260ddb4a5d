#pragma once

/// @file
/// Evaluation statistics of thesis chapter 6 (docs/MODEL.md, "Evaluation"):
/// prediction errors (Eqs. 6.1, 6.2, 6.9, 6.10), the paired t-test that
/// compares methods across subjects (Eq. 6.3, §6.1.2) and the linearised
/// passive dynamics of Table 6.4 (§6.9).
///
/// All error functions take prediction and data of the same length in the
/// same unit and throw std::invalid_argument if the lengths differ, the
/// inputs are empty or a value is not finite.

#include <cstddef>
#include <optional>
#include <span>

#include "model/parameter_set.h"

namespace fesbench::model {

/// E_RMS = sqrt(Σ (prediction − data)² / N) (Eq. 6.9, §6.9), in the data's
/// unit.
double RmsError(std::span<const double> prediction, std::span<const double> data);

/// E_ABS = Σ |prediction − data| / N (Eq. 6.10, §6.9), in the data's unit.
double AbsError(std::span<const double> prediction, std::span<const double> data);

/// Result of the normalised RMS error.
struct NormalisedRms {
  double value = 0.0;            ///< dimensionless (0.1 = 10 %).
  std::size_t samples_used = 0;  ///< N in Eq. 6.1 after exclusion.
  std::size_t samples_excluded = 0;
};

/// Normalised RMS error E_RMS = sqrt(Σ ((prediction − data)/data)² / N)
/// (Eq. 6.1, §6.1.2). Eq. 6.1 is undefined where data = 0 and explodes where
/// data is tiny (isometric torque at rest is ≈ 0 plus noise), so samples
/// with |data| ≤ exclude_below_fraction · max|data| are left out of both the
/// sum and N; the count is reported. exclude_below_fraction = 0 excludes
/// only exact zeros.
/// nullopt where Eq. 6.1 is undefined: every sample excluded (e.g. all data
/// are 0).
/// @throws std::invalid_argument as stated in the file comment, or if
///   exclude_below_fraction is outside [0, 1).
std::optional<NormalisedRms> NormalisedRmsError(std::span<const double> prediction, std::span<const double> data,
                                 double exclude_below_fraction = 0.05);

/// Averaged RMS error E_AVE = sqrt(Σ (prediction − data)²) / Σ data
/// (Eq. 6.2, §6.1.2), dimensionless.
/// nullopt where Eq. 6.2 is undefined (Σ data = 0).
/// @throws std::invalid_argument as stated in the file comment.
std::optional<double> AveragedRmsError(std::span<const double> prediction, std::span<const double> data);

/// Result of a paired Student's t-test (Eq. 6.3).
struct PairedTTestResult {
  double mean_difference = 0.0;  ///< d̄ = mean(a − b); positive: a has more error.
  double sd_difference = 0.0;    ///< S_d, sample standard deviation (n − 1).
  std::size_t n = 0;
  double t = 0.0;        ///< d̄ / (S_d / √n).
  double df = 0.0;       ///< n − 1.
  double p_value = 1.0;  ///< two-sided.
  double confidence = 0.95;
  double t_critical = 0.0;   ///< two-sided critical value at `confidence`.
  bool significant = false;  ///< |t| > t_critical.
};

/// Paired t-test of the differences a[i] − b[i] (Eq. 6.3, §6.1.2), e.g. the
/// errors of two methods on the same subjects. The t distribution is
/// Boost.Math's students_t.
/// @throws std::invalid_argument if the lengths differ, n < 2, a value is
///   not finite, confidence is outside (0, 1), or all differences are equal
///   (S_d = 0: t undefined).
PairedTTestResult PairedTTest(std::span<const double> a, std::span<const double> b,
                              double confidence = 0.95);

/// Two-sided critical value of Student's t for df degrees of freedom at the
/// given confidence (2.131 for df 15, 2.014 for df 45 at 0.95).
/// @throws std::invalid_argument if df <= 0 or confidence outside (0, 1).
double StudentTCritical(double df, double confidence = 0.95);

/// Which one-sided slope of a piecewise-linear curve to use at the
/// operating point: at a breakpoint the two differ (Table 6.4 linearises the
/// sequential set on its negative-velocity side).
enum class SlopeSide { kCentral, kLeft, kRight };

/// The passive system J·θ̈ + τ_ptv(θ̇) + τ_pta(θ) = 0 (Eq. 4.32) linearised
/// about an operating point (§6.9, Table 6.4).
struct PassiveLinearisation {
  double angle_deg = 0.0;
  double velocity_deg_s = 0.0;
  double stiffness_nm_per_rad = 0.0;     ///< k = dτ_pta/dθ.
  double damping_nm_s_per_rad = 0.0;     ///< b = dτ_ptv/dθ̇.
  double natural_frequency_rad_s = 0.0;  ///< ω_n = √(k/J).
  double damping_ratio = 0.0;            ///< ζ = b / (2√(kJ)).
  /// Damped period T = 2π / (ω_n √(1 − ζ²)), s; Table 6.4 lists 0.5·T.
  /// nullopt when ζ ≥ 1 (no oscillation).
  std::optional<double> damped_period_s;
  /// M2/M1: ratio of successive (opposite-sign, half a period apart) peak
  /// magnitudes of the free response, exp(−πζ / √(1 − ζ²)); nullopt when
  /// ζ ≥ 1. (Reproduces Table 6.4's simultaneous row: ζ 0.137 → 0.65 vs
  /// 0.64 printed.)
  std::optional<double> peak_ratio;
};

/// Slopes are exact one-sided or central differences of the PWL curves
/// (step 1e-6 deg or deg/s, well inside any segment), converted to per-rad.
struct LinearisationOptions {
  SlopeSide angle_side = SlopeSide::kCentral;
  SlopeSide velocity_side = SlopeSide::kCentral;
};

/// Linearises passive about (angle_deg, velocity_deg_s).
/// @throws std::invalid_argument if a curve is empty, J ≤ 0, the point is
///   not finite, or the stiffness is not positive (no stable oscillator:
///   ω_n undefined).
PassiveLinearisation LinearisePassive(const PassiveParams& passive, double angle_deg,
                                      double velocity_deg_s,
                                      const LinearisationOptions& options = {});

/// The passive rest angle: the stable equilibrium of the free limb,
/// τ_pta(θ) + τ_ptv(0) = 0 with dτ_pta/dθ > 0 (for unreferenced curves with
/// τ_ptv(0) = 0 this is τ_pta(θ) = 0; with the §6.5 referencing the constant
/// in τ_ptv(0) matters). Roots are searched on the breakpoints of τ_pta
/// (end values are held beyond them); of several stable roots the one
/// nearest hint_deg is returned. Where τ_pta + τ_ptv(0) is 0 over a whole
/// segment the segment's midpoint is taken.
/// nullopt if no stable root exists inside the breakpoints (a leg that
/// does not hang still).
/// @throws std::invalid_argument if a curve is empty.
std::optional<double> FindPassiveRestAngle(const PassiveParams& passive, double hint_deg = 90.0);

/// FindPassiveRestAngle where a rest angle must exist (a leg's truth, a
/// table of identified sets).
/// @throws std::invalid_argument if a curve is empty or there is no stable
///   root.
double PassiveRestAngle(const PassiveParams& passive, double hint_deg = 90.0);

}  // namespace fesbench::model
