#pragma once

/// @file
/// The muscle–tendon–joint model's static functions (thesis Fig. 3-9,
/// Eq. 3.16; DESIGN.md §3) for every model variant behind one interface:
/// τ_pta(θ), τ_ptv(θ̇), the active gain τ_scale·f_ata(θ)·f_atv(θ̇) and J.
/// With f_stim from the contraction dynamics the equation of motion is
///   J·θ̈ = τ_motor − τ_pta(θ) − τ_ptv(θ̇) − f_stim·ActiveGain(θ, θ̇)
/// (θ̈ in rad/s², the quadriceps torque is an extensor torque).
///
/// Variants (ModelKind):
///   full:                      PWL τ_pta, τ_ptv, f_ata, f_atv (Fig. 3-9);
///   torque_generator:          f_ata = f_atv = 1 (§5.5.1);
///   single_segment:            f_ata = a·θ + b, f_atv = c·θ̇ + d (Eqs. 5.1–5.2);
///   static_gain_pwl_velocity:  f_ata = 1 (the constant is in τ_scale), PWL f_atv (§7.3);
///   parametric:                τ_pta = mgl·sin θ + k₁·e^(k₂θ) + offset (Eq. 7.3),
///                              Gaussian f_ata, two-segment f_atv (§7.4.4).
/// Every gain f_ata, f_atv is clamped at ≥ 0 when evaluated.
///
/// Evaluation is cheap (no allocation, no virtual call, branch-light curve
/// look-up) and const, so one JointModel may be shared between threads.

#include <cstdint>
#include <optional>
#include <vector>

#include "model/parameter_set.h"

namespace fesbench::model {

/// A piecewise-linear curve prepared for fast evaluation: same values as
/// PiecewiseLinear (linear between breakpoints, ends held), with per-segment
/// slopes precomputed.
class FastCurve {
 public:
  FastCurve() = default;
  /// @throws std::invalid_argument if the curve is empty.
  explicit FastCurve(const PiecewiseLinear& curve);

  double operator()(double x) const {
    const std::size_t m = x_.size();
    if (x <= x_[0]) return y_[0];
    if (x >= x_[m - 1]) return y_[m - 1];
    // Segment index: the number of interior breakpoints ≤ x (branch-free).
    std::size_t i = 0;
    for (std::size_t j = 1; j + 1 < m; ++j) i += static_cast<std::size_t>(x >= x_[j]);
    return y_[i] + slope_[i] * (x - x_[i]);
  }

 private:
  std::vector<double> x_, y_, slope_;
};

/// Two piecewise-linear curves f(x), g(x) tabulated on the union of their
/// breakpoints, so one segment look-up evaluates both (exactly: both are
/// linear between consecutive union breakpoints, ends held). The look-up is
/// O(1) through a uniform bucket index over the breakpoints.
class CurvePairTable {
 public:
  CurvePairTable() = default;
  /// @throws std::invalid_argument if either curve is empty.
  CurvePairTable(const PiecewiseLinear& f, const PiecewiseLinear& g);

  /// Sets f_out = f(x), g_out = g(x).
  void Evaluate(double x, double& f_out, double& g_out) const {
    const std::size_t m = x_.size();
    if (x <= x_[0]) {
      f_out = f_[0];
      g_out = g_[0];
      return;
    }
    if (x >= x_[m - 1]) {
      f_out = f_[m - 1];
      g_out = g_[m - 1];
      return;
    }
    // Bucket look-up: cells no wider than the narrowest segment hold at most
    // one interior breakpoint, so the scan below runs at most once (more
    // only when the cell count was capped).
    std::size_t k = static_cast<std::size_t>((x - x_[0]) * inv_cell_);
    if (k >= bucket_.size()) k = bucket_.size() - 1;
    std::size_t i = bucket_[k];
    while (i + 2 < m && x >= x_[i + 1]) ++i;
    const double dx = x - x_[i];
    f_out = f_[i] + f_slope_[i] * dx;
    g_out = g_[i] + g_slope_[i] * dx;
  }

 private:
  std::vector<double> x_, f_, f_slope_, g_, g_slope_;
  std::vector<std::uint32_t> bucket_;  // first segment of each uniform cell
  double inv_cell_ = 0.0;
};

/// The static part of one model variant, built from a ParameterSet.
class JointModel {
 public:
  /// Builds the model of `params` as the variant `kind_override` if given,
  /// else params.model.
  /// @throws std::invalid_argument if passive.inertia_kgm2 is not finite and
  ///   > 0, active.torque_scale_nm is not finite and ≥ 0, a curve the variant
  ///   uses is empty, or a variant parameter is not finite (parametric:
  ///   also ata_width_deg must be > 0). The message names the field.
  static JointModel FromParameters(const ParameterSet& params,
                                   std::optional<ModelKind> kind_override = std::nullopt);

  ModelKind kind() const { return kind_; }
  /// J, kg·m².
  double inertia_kgm2() const { return inertia_kgm2_; }
  /// τ_scale, N·m.
  double torque_scale_nm() const { return torque_scale_nm_; }

  /// τ_pta(θ), N·m, θ in degrees (includes gravity).
  double PassiveAngleTorque(double angle_deg) const;
  /// τ_ptv(θ̇), N·m, θ̇ in deg/s.
  double PassiveVelocityTorque(double velocity_deg_s) const;
  /// f_ata(θ) ≥ 0 (dimensionless).
  double AngleGain(double angle_deg) const;
  /// f_atv(θ̇) ≥ 0 (dimensionless).
  double VelocityGain(double velocity_deg_s) const;
  /// τ_scale·f_ata(θ)·f_atv(θ̇), N·m: the active torque per unit f_stim.
  double ActiveGain(double angle_deg, double velocity_deg_s) const;
  /// θ̈ in deg/s² from the equation of motion
  /// J·θ̈ = τ_motor − τ_pta − τ_ptv − f_stim·ActiveGain (θ̈ converted from rad/s²).
  double AccelerationDegS2(double angle_deg, double velocity_deg_s, double activation,
                           double motor_torque_nm = 0.0) const;

 private:
  JointModel() = default;
  // τ_pta + τ_ptv and the active gain at (θ, θ̇) with two table look-ups.
  void PassiveAndGain(double angle_deg, double velocity_deg_s, double& passive_nm,
                      double& gain_nm) const;

  ModelKind kind_ = ModelKind::kFull;
  double inertia_kgm2_ = 1.0;
  double accel_deg_per_nm_ = 0.0;  // (180/π)/J: N·m → deg/s²
  double torque_scale_nm_ = 0.0;
  // Angle table: (τ_pta, f_ata); velocity table: (τ_ptv, f_atv). Variants
  // without a PWL gain tabulate the constant 1; parametric and
  // single_segment gains (and parametric τ_pta) are computed in closed form.
  CurvePairTable angle_table_, velocity_table_;
  SingleSegmentParams single_segment_;
  ParametricParams parametric_;
};

}  // namespace fesbench::model
