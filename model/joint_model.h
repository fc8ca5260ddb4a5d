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
  double PassiveVelocityTorque(double velocity_deg_s) const { return ptv_(velocity_deg_s); }
  /// f_ata(θ) ≥ 0 (dimensionless).
  double AngleGain(double angle_deg) const;
  /// f_atv(θ̇) ≥ 0 (dimensionless).
  double VelocityGain(double velocity_deg_s) const;
  /// τ_scale·f_ata(θ)·f_atv(θ̇), N·m: the active torque per unit f_stim.
  double ActiveGain(double angle_deg, double velocity_deg_s) const {
    return torque_scale_nm_ * AngleGain(angle_deg) * VelocityGain(velocity_deg_s);
  }
  /// θ̈ in deg/s² from the equation of motion
  /// J·θ̈ = τ_motor − τ_pta − τ_ptv − f_stim·ActiveGain (θ̈ converted from rad/s²).
  double AccelerationDegS2(double angle_deg, double velocity_deg_s, double activation,
                           double motor_torque_nm = 0.0) const;

 private:
  JointModel() = default;

  ModelKind kind_ = ModelKind::kFull;
  double inertia_kgm2_ = 1.0;
  double torque_scale_nm_ = 0.0;
  FastCurve pta_, ptv_, ata_, atv_;
  SingleSegmentParams single_segment_;
  ParametricParams parametric_;
};

}  // namespace fesbench::model
