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
  const Line& LineAt(double x, std::size_t& segment) const { return view().LineAt(x, segment); }

  /// The table's arrays, for a loop of look-ups that holds them in
  /// registers (LineAt through the vectors reloads their data pointers).
  struct View {
    const double* lower;
    const Line* lines;
    const Line& LineAt(double x, std::size_t& segment) const {
      // lower is {NaN, b₀, …, b_{m−1}, NaN}: no comparison with the NaN
      // ends holds, so the scans stop at the held segments 0 and m.
      std::size_t i = segment;
      while (x < lower[i]) --i;
      while (x >= lower[i + 1]) ++i;
      segment = i;
      return lines[i];
    }
  };
  View view() const { return {lower_.data(), lines_.data()}; }

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
  /// parametric): then FreeSwingRk4Step applies.
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
    return ParametricAcceleration(angle_deg, velocity_deg_s, activation, segments, motor_torque_nm);
  }

  /// One RK4 step of free swing (τ_motor = 0; has_scaled_tables() only)
  /// from (θ, θ̇) over h, with f_stim a0, a_half, a_end at its start,
  /// middle and end: Rk4Stages over AccelerationDegS2, arranged for the
  /// dependency chain a simulation waits on (the same value up to
  /// rounding). On a stage's cells θ̈ = P(θ) + V(θ̇) − f_stim·G(θ)·H(θ̇) is
  /// a line in θ̇, D + E·θ̇, so the stage's next velocity base + c·θ̈ is one
  /// multiply-add from the stage's θ̇; the stage's θ = θ₀ + c'·ω (ω the
  /// previous stage's velocity) enters G and P as θ₀'s part, known early,
  /// plus c'·ω times the slope, so D and E wait for ω by two operations
  /// instead of θ's sum, its line and the product with f_stim. The step's
  /// θ̇ is ω₄ plus the stage differences, θ̇₀ + (h/6)(k₁ + 2k₂ + 2k₃ + k₄)
  /// with h·k₁/2 = ω₂ − θ̇₀, h·k₂/2 = ω₃ − θ̇₀, h·k₃ = ω₄ − θ̇₀. Inlined
  /// into the simulation's loop, with the tables' arrays and the segment
  /// hints held in registers for the step.
  [[gnu::always_inline]] void FreeSwingRk4Step(double& angle_deg, double& velocity_deg_s, double h,
                                               double a0, double a_half, double a_end,
                                               Segments& segments) const {
    const double th = angle_deg, om = velocity_deg_s, hh = 0.5 * h;
    std::size_t sa = segments.angle, sv = segments.velocity;
    const LinePairTable::View angle = scaled_angle_.view(), velocity = scaled_velocity_.view();
    // Stage 1 at (θ, θ̇).
    const LinePairTable::Line& a1 = angle.LineAt(th, sa);
    const double p1 = a1.f0 + a1.f1 * th;
    const double x1 = a0 * (a1.g0 + a1.g1 * th);
    const LinePairTable::Line& v1 = velocity.LineAt(om, sv);
    const double d1 = (p1 + v1.f0) - x1 * v1.g0, e1 = v1.f1 - x1 * v1.g1;
    const double om2 = (om + hh * d1) + (hh * e1) * om;
    // Stage 2 at (θ + h/2·θ̇, ω₂).
    const double th2 = th + hh * om;
    const LinePairTable::Line& a2 = angle.LineAt(th2, sa);
    const LinePairTable::Line& v2 = velocity.LineAt(om2, sv);
    const double x2 = a_half * (a2.g0 + a2.g1 * th2);
    const double d2 = (a2.f0 + a2.f1 * th2 + v2.f0) - x2 * v2.g0, e2 = v2.f1 - x2 * v2.g1;
    const double om3 = (om + hh * d2) + (hh * e2) * om2;
    // Stage 3 at (θ + h/2·ω₂, ω₃): θ's part and ω₂'s part apart.
    const LinePairTable::Line& a3 = angle.LineAt(th + hh * om2, sa);
    const LinePairTable::Line& v3 = velocity.LineAt(om3, sv);
    const double x3 = a_half * (a3.g0 + a3.g1 * th) + (a_half * a3.g1 * hh) * om2;
    const double p3 = (a3.f0 + a3.f1 * th + v3.f0) + (a3.f1 * hh) * om2;
    const double om4 = ((om + h * p3) - (h * v3.g0) * x3) + (h * v3.f1 - (h * v3.g1) * x3) * om3;
    // Stage 4 at (θ + h·ω₃, ω₄).
    const LinePairTable::Line& a4 = angle.LineAt(th + h * om3, sa);
    const LinePairTable::Line& v4 = velocity.LineAt(om4, sv);
    const double x4 = a_end * (a4.g0 + a4.g1 * th) + (a_end * a4.g1 * h) * om3;
    const double p4 = (a4.f0 + a4.f1 * th + v4.f0) + (a4.f1 * h) * om3;
    const double h6 = h / 6.0;
    const double base = (om2 + 2.0 * om3 - om) * (1.0 / 3.0) + h6 * (p4 - v4.g0 * x4);
    angle_deg = th + h6 * ((om + 2.0 * om2) + (2.0 * om3 + om4));
    velocity_deg_s = base + ((1.0 / 3.0) + h6 * (v4.f1 - v4.g1 * x4)) * om4;
    segments = {sa, sv};
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
