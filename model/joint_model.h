#pragma once

/// @file
/// The muscle–tendon–joint model's static functions (thesis Fig. 3-9,
/// Eq. 3.16; docs/MODEL.md) for every model variant behind one interface:
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

#include <algorithm>
#include <optional>
#include <vector>

#include "model/parameter_set.h"

namespace fesbench::model {

/// Two piecewise-linear curves f(x), g(x) tabulated on the union of their
/// breakpoints, so one segment look-up evaluates both (exactly: both are
/// linear between consecutive union breakpoints, ends held).
///
/// The look-up is a scan with ordinary branches rather than arithmetic
/// indexing: along a simulated trajectory the segment rarely changes, the
/// branches are predicted, and the segment's coefficients load before x is
/// known, taking the look-up off the integrator's critical path (measured
/// ~30 % faster per prediction than a branch-free cell index). A caller
/// that evaluates along a trajectory passes the segment of its last
/// look-up (a hint), where the scan starts: usually no step at all.
class CurvePairTable {
 public:
  CurvePairTable() = default;
  /// @throws std::invalid_argument if either curve is empty.
  CurvePairTable(const PiecewiseLinear& f, const PiecewiseLinear& g);

  /// Sets f_out = f(x), g_out = g(x).
  void Evaluate(double x, double& f_out, double& g_out) const {
    std::size_t segment = 0;
    Evaluate(x, f_out, g_out, segment);
  }

  /// The same, the scan started at `segment` (any value below the number
  /// of breakpoints; 0 at first), which receives the segment of x. The
  /// values are those of the scan from 0: the segment found is the same.
  void Evaluate(double x, double& f_out, double& g_out, std::size_t& segment) const {
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
    // x_[0] < x < x_[m − 1] here: the scans stop inside 0 … m − 2.
    std::size_t i = segment < m - 1 ? segment : m - 2;
    if (m > kLinearScanMax && !(x >= x_[i] && x < x_[i + 1])) [[unlikely]] {
      i = SegmentBySearch(x);
    } else {
      while (x < x_[i]) --i;
      while (x >= x_[i + 1]) ++i;
    }
    segment = i;
    const double dx = x - x_[i];
    f_out = f_[i] + f_slope_[i] * dx;
    g_out = g_[i] + g_slope_[i] * dx;
  }

 private:
  static constexpr std::size_t kLinearScanMax = 32;
  // Binary search for long tables (x strictly inside the breakpoints).
  std::size_t SegmentBySearch(double x) const;
  std::vector<double> x_, f_, f_slope_, g_, g_slope_;
};

/// Two functions f(x), g(x), linear on every segment of one partition of
/// the real line, each segment stored as its two lines f = f₀ + f₁·x,
/// g = g₀ + g₁·x: an evaluation is a segment scan (predicted branches, as
/// CurvePairTable's) and two multiply-adds, with no subtraction of the
/// segment's start or division on the way from x to the values.
class LinePairTable {
 public:
  LinePairTable() = default;
  /// f and g given by their values at breakpoints b (strictly increasing,
  /// non-empty; not checked), linear between them; beyond the ends f is
  /// held and g continues with the given slopes (0: held).
  LinePairTable(std::vector<double> b, const std::vector<double>& f, const std::vector<double>& g,
                double g_left_slope = 0.0, double g_right_slope = 0.0);

  /// Sets f_out = f(x), g_out = g(x); the scan starts at `segment` (0 at
  /// first, then the segment of the last look-up, which it receives).
  void Evaluate(double x, double& f_out, double& g_out, std::size_t& segment) const {
    const Line& l = LineAt(x, segment);
    f_out = l.f0 + l.f1 * x;
    g_out = l.g0 + l.g1 * x;
  }

  /// The lines of x's segment, f = f0 + f1·x, g = g0 + g1·x (the scan as
  /// in Evaluate).
  struct Line {
    double f0 = 0.0, f1 = 0.0, g0 = 0.0, g1 = 0.0;
  };
  const Line& LineAt(double x, std::size_t& segment) const {
    // lower_ is {NaN, b₀, …, b_{m−1}, NaN}: no comparison with the NaN ends
    // holds, so the scans stop at the held segments 0 and m.
    std::size_t i = segment;
    while (x < lower_[i]) --i;
    while (x >= lower_[i + 1]) ++i;
    segment = i;
    return lines_[i];
  }

 private:
  std::vector<double> lower_;  // segment i is [lower_[i], lower_[i + 1])
  std::vector<Line> lines_;
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
                           double motor_torque_nm = 0.0) const {
    Segments segments;
    return AccelerationDegS2(angle_deg, velocity_deg_s, activation, segments, motor_torque_nm);
  }

  /// Whether AccelerationDegS2 reads scaled tables (every variant but
  /// parametric): then FreeSwingStage applies.
  bool has_scaled_tables() const { return scaled_tables_; }

  /// The curve segments of the last evaluation (CurvePairTable's hints): a
  /// simulation keeps one and passes it to every evaluation along its
  /// trajectory, so the look-ups start where the state last was.
  struct Segments {
    std::size_t angle = 0;
    std::size_t velocity = 0;
  };
  /// The same with the look-ups started at `segments`, which receive the
  /// segments of this state (the value is the same whatever they held).
  ///
  /// For the variants whose curves are all piecewise linear (every variant
  /// but parametric; single_segment's gains are lines) the terms come scaled
  /// into θ̈ from two LinePairTables, P(θ) = −k·τ_pta(θ), G(θ) = k·τ_scale·f_ata⁺(θ),
  /// V(θ̇) = −k·τ_ptv(θ̇), H(θ̇) = f_atv⁺(θ̇), k = (180/π)/J, the clamps at 0
  /// tabulated (a breakpoint where a gain crosses 0), so that
  ///   θ̈ = (P(θ) + k·τ_motor + V(θ̇)) − (f_stim·G(θ))·H(θ̇):
  /// along a simulated trajectory θ̇ is the state that changes last, and
  /// from it to θ̈ are two multiply-adds, a multiplication and a subtraction.
  /// The same value as the unscaled form up to rounding (~1e-15 relative).
  double AccelerationDegS2(double angle_deg, double velocity_deg_s, double activation,
                           Segments& segments, double motor_torque_nm = 0.0) const {
    if (scaled_tables_) [[likely]] {
      double p = 0.0, g = 0.0, v = 0.0, h = 0.0;
      scaled_angle_.Evaluate(angle_deg, p, g, segments.angle);
      scaled_velocity_.Evaluate(velocity_deg_s, v, h, segments.velocity);
      return (p + motor_torque_nm * accel_deg_per_nm_ + v) - (activation * g) * h;
    }
    return ParametricAcceleration(angle_deg, velocity_deg_s, activation, segments,
                                  motor_torque_nm);
  }

  /// One stage of an RK4 step in free swing (τ_motor = 0; has_scaled_tables()
  /// only): θ̈ at (θ, θ̇), as AccelerationDegS2, and the next stage's
  /// velocity base + c·θ̈. On θ̇'s segment θ̈ is a line in θ̇,
  /// θ̈ = D + E·θ̇ with D = P + v₀ − f_stim·G·h₀, E = v₁ − f_stim·G·h₁, so
  /// base + c·θ̈ = (base + c·D) + (c·E)·θ̇: one multiply-add from θ̇ (the
  /// state each stage waits for) instead of the whole right-hand side; the
  /// coefficients wait only for θ, known a stage earlier. The same value
  /// as base + c·θ̈ up to rounding.
  struct Stage {
    double accel_deg_s2;
    double next_velocity_deg_s;
  };
  Stage FreeSwingStage(double angle_deg, double velocity_deg_s, double activation,
                       double base_deg_s, double c_s, Segments& segments) const {
    double p = 0.0, g = 0.0;
    scaled_angle_.Evaluate(angle_deg, p, g, segments.angle);
    const LinePairTable::Line& l = scaled_velocity_.LineAt(velocity_deg_s, segments.velocity);
    const double ag = activation * g;
    const double v = l.f0 + l.f1 * velocity_deg_s, h = l.g0 + l.g1 * velocity_deg_s;
    const double d = (p + l.f0) - ag * l.g0, e = l.f1 - ag * l.g1;
    return {(p + v) - ag * h, (base_deg_s + c_s * d) + (c_s * e) * velocity_deg_s};
  }

 private:
  JointModel() = default;
  // AccelerationDegS2 of the parametric variant (out of line: the tables'
  // path stays small enough to inline into a simulation's loop).
  double ParametricAcceleration(double angle_deg, double velocity_deg_s, double activation,
                                Segments& segments, double motor_torque_nm) const;
  // τ_pta + τ_ptv and the active gain at (θ, θ̇) with two table look-ups
  // (inline: the simulation's hot path).
  void PassiveAndGain(double angle_deg, double velocity_deg_s, double& passive_nm, double& gain_nm,
                      Segments& segments) const {
    double pta = 0.0, ata = 1.0, ptv = 0.0, atv = 1.0;
    angle_table_.Evaluate(angle_deg, pta, ata, segments.angle);
    velocity_table_.Evaluate(velocity_deg_s, ptv, atv, segments.velocity);
    if (kind_ == ModelKind::kSingleSegment || kind_ == ModelKind::kParametric) {
      passive_nm = PassiveAngleTorque(angle_deg) + ptv;
      gain_nm = torque_scale_nm_ * AngleGain(angle_deg) * VelocityGain(velocity_deg_s);
      return;
    }
    // Eq. 3.16: τ_scale·f_ata(θ)·f_atv(θ̇), gains clamped at 0 (tabulated as 1
    // for variants without the curve).
    passive_nm = pta + ptv;
    gain_nm = torque_scale_nm_ * (ata > 0.0 ? ata : 0.0) * (atv > 0.0 ? atv : 0.0);
  }

  ModelKind kind_ = ModelKind::kFull;
  double inertia_kgm2_ = 1.0;
  double accel_deg_per_nm_ = 0.0;  // (180/π)/J: N·m → deg/s²
  double torque_scale_nm_ = 0.0;
  // Angle table: (τ_pta, f_ata); velocity table: (τ_ptv, f_atv). Variants
  // without a PWL gain tabulate the constant 1; parametric and
  // single_segment gains (and parametric τ_pta) are computed in closed form.
  CurvePairTable angle_table_, velocity_table_;
  // θ̈'s terms (P, G) and (V, H) of AccelerationDegS2, for the variants
  // with piecewise-linear curves only (scaled_tables_).
  bool scaled_tables_ = false;
  LinePairTable scaled_angle_, scaled_velocity_;
  SingleSegmentParams single_segment_;
  ParametricParams parametric_;
};

}  // namespace fesbench::model
