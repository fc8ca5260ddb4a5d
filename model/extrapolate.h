#pragma once

/// @file
/// Curves beyond the data they were identified from (issue: "no curve held
/// flat beyond its data"). A piecewise-linear curve holds its end values
/// outside its breakpoints (Eq. 4.27); a τ_pta identified over 76–90° and
/// held flat beyond would let gravity vanish at full extension. These
/// functions add breakpoints outside the identified range whose ordinates
/// follow a physically grounded form fitted where the data are:
///  - τ_pta: gravity plus exponential end-range stiffness, the parametric
///    model of §7.4.4 (Eq. 7.3, Franken's form) with the gravity term
///    m·g·l·sin(θ − θ_h) (shank vertical at θ_h) and one exponential per end:
///      τ(θ) = a·sin θ + b·cos θ + c − k_e·e^(−(θ − lo)/w_e) + k_f·e^((θ − hi)/w_f),
///    k_e, k_f ≥ 0 (tissue resists at each end), w_e, w_f chosen by grid;
///  - f_ata: a Gaussian (§7.4.4 candidates) fitted to ln f_ata, never above
///    the edge value (not rising without data), ≥ 0; held if the data are
///    not Gaussian-shaped (no negative curvature);
///  - τ_ptv: the edge segment's slope continued (viscous), if ≥ 0;
///  - f_atv: the edge segment's slope continued, clamped to [0, edge value].
/// And the share of a trajectory outside the identified ranges.

#include <optional>
#include <span>

#include "model/parameter_set.h"
#include "model/piecewise_linear.h"

namespace fesbench::model {

/// Eq. 7.3-type fit of τ_pta over [lo, hi] (see the file comment).
struct PassiveAngleForm {
  double a_nm = 0.0, b_nm = 0.0, c_nm = 0.0;    ///< gravity a·sin θ + b·cos θ, constant c.
  double ext_nm = 0.0, ext_width_deg = 10.0;    ///< k_e ≥ 0, w_e.
  double flex_nm = 0.0, flex_width_deg = 10.0;  ///< k_f ≥ 0, w_f.
  double lo_deg = 0.0, hi_deg = 0.0;            ///< the fitted range.
  double rms_nm = 0.0;                          ///< fit residual over [lo, hi].
  /// m·g·l = √(a² + b²), N·m, and θ_h, the angle where gravity vanishes.
  double mgl_nm() const;
  double hang_deg() const;
  double operator()(double angle_deg) const;
};

/// Fits PassiveAngleForm to τ_pta sampled every 1° over [lo, hi]. With
/// mgl_prior_nm > 0 and a range under 60° the gravity amplitude is held at
/// that value (a range that short cannot separate sin, cos and constant);
/// otherwise it is fitted.
/// @throws std::invalid_argument if the curve is empty or hi − lo < 5°.
PassiveAngleForm FitPassiveAngleForm(const PiecewiseLinear& torque_angle, double lo_deg,
                                     double hi_deg, double mgl_prior_nm = 0.0);

/// τ_pta identified over [lo, hi] extended to [out_lo, out_hi] with
/// breakpoints every step_deg outside [lo, hi] following `form`, shifted to
/// meet the curve at each edge (continuity). Breakpoints of the curve
/// outside [lo, hi] are replaced.
PiecewiseLinear ExtendPassiveAngle(const PiecewiseLinear& torque_angle,
                                   const PassiveAngleForm& form, double out_lo_deg,
                                   double out_hi_deg, double step_deg = 5.0);

/// f_ata identified over [lo, hi] extended to [out_lo, out_hi] (file comment).
PiecewiseLinear ExtendActiveAngle(const PiecewiseLinear& gain, double lo_deg, double hi_deg,
                                  double out_lo_deg, double out_hi_deg, double step_deg = 10.0);

/// τ_ptv (passive = true) or f_atv (false) identified over [lo, hi] extended
/// to [out_lo, out_hi] by continuing the edge segments (file comment).
PiecewiseLinear ExtendVelocityCurve(const PiecewiseLinear& curve, double lo_deg_s, double hi_deg_s,
                                    double out_lo_deg_s, double out_hi_deg_s, bool passive);

/// Share (0–1) of the samples i whose angle_deg[i] lies outside an angle
/// range of provenance.identified_range_deg or whose velocity_deg_s[i] lies
/// outside a velocity range of identified_range_deg_s; nullopt if the set
/// records no range or there are no samples. velocity_deg_s may be empty
/// (then only the angle ranges count).
/// @throws std::invalid_argument if velocity_deg_s is non-empty and of
///   another length than angle_deg.
std::optional<double> ShareOutsideIdentifiedRanges(const Provenance& provenance,
                                                   std::span<const double> angle_deg,
                                                   std::span<const double> velocity_deg_s);

}  // namespace fesbench::model
