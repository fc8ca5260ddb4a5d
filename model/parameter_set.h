#pragma once

/// @file
/// The parameter set of the muscle–tendon–joint model (thesis ch. 3,
/// Fig. 3-9; docs/MODEL.md): the unit every identification produces and every
/// prediction consumes. A plain value type: algorithms take it by const
/// reference and never modify it.
///
/// Conventions (docs/ARCHITECTURE.md, units): angle θ in degrees of knee flexion (0 = full
/// extension), velocity in deg/s, torque in N·m positive in the flexion
/// direction, stimulation in mA. The quadriceps torque τ_act is an extensor
/// torque: it enters the equation of motion with a minus sign,
///   J·θ̈ = τ_motor − τ_pta(θ) − τ_ptv(θ̇) − τ_act.

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "model/piecewise_linear.h"

namespace fesbench::model {

/// Model variants selectable by name (docs/MODEL.md, thesis §5.5.1, §7.3,
/// §7.4.4).
enum class ModelKind {
  kFull,                   ///< PWL f_ata(θ), PWL f_atv(θ̇) (Fig. 3-9).
  kTorqueGenerator,        ///< f_ata = f_atv = 1 (§5.5.1).
  kSingleSegment,          ///< f_ata = Aθ + B, f_atv = Cθ̇ + D (Eqs. 5.1–5.2).
  kStaticGainPwlVelocity,  ///< f_ata constant (in τ_scale), PWL f_atv (§7.3).
  kParametric,             ///< Eq. 7.3 τ_pta, Gaussian f_ata, two-segment f_atv (§7.4.4).
};

/// The wire name of a model kind: "full", "torque_generator",
/// "single_segment", "static_gain_pwl_velocity", "parametric".
std::string_view ModelKindName(ModelKind kind);
/// Inverse of ModelKindName; nullopt for an unknown name.
std::optional<ModelKind> ParseModelKind(std::string_view name);
/// Every model kind, in declaration order.
const std::vector<ModelKind>& AllModelKinds();

/// Linear contraction dynamics H_n(s) = a^n / (s + a)^n, unit DC gain
/// (Eqs. 3.21, 4.1–4.4).
struct ContractionParams {
  int order = 3;             ///< n: 2 or 3.
  double pole_per_s = 25.0;  ///< a > 0, s⁻¹. Twitch peak at (n − 1)/a.
  friend bool operator==(const ContractionParams&, const ContractionParams&) = default;
};

/// Passive joint properties (§4.2). τ_pta includes gravity. Only the sum
/// τ_pta + τ_ptv is identifiable (§6.5); see ReferencePassive.
struct PassiveParams {
  double inertia_kgm2 = 0.36;       ///< J > 0, kg·m² (= N·m·s²/rad).
  PiecewiseLinear torque_angle;     ///< τ_pta: angle_deg → torque_nm.
  PiecewiseLinear torque_velocity;  ///< τ_ptv: velocity_deg_s → torque_nm.
  friend bool operator==(const PassiveParams&, const PassiveParams&) = default;
};

/// Active properties (Eq. 3.16): τ_act = τ_scale · f_stim · f_ata(θ) · f_atv(θ̇).
struct ActiveParams {
  double torque_scale_nm = 40.0;    ///< τ_scale ≥ 0, N·m.
  PiecewiseLinear torque_angle;     ///< f_ata: angle_deg → gain ≥ 0 (1 at 90°).
  PiecewiseLinear torque_velocity;  ///< f_atv: velocity_deg_s → gain ≥ 0 (1 at 0 deg/s).
  friend bool operator==(const ActiveParams&, const ActiveParams&) = default;
};

/// single_segment variant (Eqs. 5.1–5.2): f_ata = a·θ + b, f_atv = c·θ̇ + d,
/// θ in degrees, θ̇ in deg/s. Gains are clamped at 0 when evaluated.
struct SingleSegmentParams {
  double a = 0.0;  ///< per degree.
  double b = 1.0;
  double c = 0.0;  ///< per deg/s.
  double d = 1.0;
  friend bool operator==(const SingleSegmentParams&, const SingleSegmentParams&) = default;
};

/// parametric variant (§7.4.4):
///   τ_pta(θ) = mgl·sin θ + k₁·e^(k₂·θ) + offset   (Eq. 7.3, θ in radians);
///   f_ata(θ) = exp(−((θ − μ)² − (90 − μ)²) / (2σ²))  (Gaussian, 1 at 90°);
///   f_atv(θ̇) = 1 + s₋·θ̇ for θ̇ < 0, 1 + s₊·θ̇ for θ̇ ≥ 0 (two segments),
/// gains clamped at 0. τ_ptv stays the PWL curve of PassiveParams.
struct ParametricParams {
  double mgl_nm = 0.0;                   ///< m·g·l, N·m.
  double k1_nm = 0.0;                    ///< k₁, N·m.
  double k2_per_rad = 0.0;               ///< k₂, rad⁻¹.
  double offset_nm = 0.0;                ///< referencing constant (§6.5), N·m.
  double ata_peak_deg = 90.0;            ///< μ, deg.
  double ata_width_deg = 60.0;           ///< σ > 0, deg.
  double atv_slope_neg_per_deg_s = 0.0;  ///< s₋, per deg/s.
  double atv_slope_pos_per_deg_s = 0.0;  ///< s₊, per deg/s.
  friend bool operator==(const ParametricParams&, const ParametricParams&) = default;
};

/// A closed interval [lo, hi] of a curve's abscissa.
struct CurveRange {
  double lo = 0.0;
  double hi = 0.0;
  bool Contains(double x) const { return x >= lo && x <= hi; }
  friend bool operator==(const CurveRange&, const CurveRange&) = default;
};

/// Where a parameter set came from (docs/MODEL.md, "The parameter set": provenance).
struct Provenance {
  std::string irc_method;      ///< e.g. "ramp_correlation".
  std::string passive_method;  ///< "sequential", "simultaneous", "free_swing".
  std::string active_method;   ///< e.g. "log_least_squares".
  /// How J was obtained: "given" (a value or a stored set), "anthropometric"
  /// (Eq. 4.13), "free_swing" (fitted, §4.2.3), "release_holds" (measured by
  /// the rapid routine's holds, IdentifyRapid); "" when not recorded.
  std::string inertia_method;
  std::optional<std::int64_t> active_trial_id;
  std::vector<std::int64_t> trial_ids;
  std::map<std::string, double> fit_rms;  ///< per fitted part, in that part's unit.
  std::vector<std::string> warnings;
  std::string software_version;
  /// The range each curve was identified over (the data it was fitted to;
  /// beyond it the curve is extrapolated, model/extrapolate.h): angle ranges
  /// (deg) keyed "tau_pta", "f_ata"; velocity ranges (deg/s) keyed
  /// "tau_ptv", "f_atv". Empty when the method did not record them.
  std::map<std::string, CurveRange> identified_range_deg;
  std::map<std::string, CurveRange> identified_range_deg_s;
  friend bool operator==(const Provenance&, const Provenance&) = default;
};

/// A complete parameter set. Fields a variant does not use keep their values
/// and are ignored by that variant.
struct ParameterSet {
  ModelKind model = ModelKind::kFull;
  PiecewiseLinear irc;  ///< R(u): stim_ma → activation in [0, 1].
  ContractionParams contraction;
  PassiveParams passive;
  ActiveParams active;
  SingleSegmentParams single_segment;  ///< used by kSingleSegment.
  ParametricParams parametric;         ///< used by kParametric.
  Provenance provenance;
  friend bool operator==(const ParameterSet&, const ParameterSet&) = default;
};

/// Reference angle and velocity of the curve normalisation (§6.5, §6.7).
inline constexpr double kReferenceAngleDeg = 90.0;
inline constexpr double kReferenceVelocityDegS = 0.0;

/// §6.5 referencing: shifts τ_pta so that τ_pta(90°) = 0 and adds the same
/// constant to τ_ptv, leaving τ_pta + τ_ptv (and every simulation) unchanged.
/// @throws std::invalid_argument if either curve is empty.
PassiveParams ReferencePassive(const PassiveParams& passive);

/// §6.7 normalisation: divides f_ata by f_ata(90°) and f_atv by f_atv(0),
/// multiplying τ_scale by both, so τ_act is unchanged.
/// @throws std::invalid_argument if a curve is empty or its reference value
///   is not positive.
ActiveParams NormaliseActive(const ActiveParams& active);

/// A plausible parameter set of a healthy knee in the thesis's ranges (full
/// model, 3rd-order pole 25 s⁻¹, J = 0.36 kg·m², threshold 20 mA, saturation
/// 45 mA, τ_scale 40 N·m); for tests, examples and defaults.
ParameterSet ExampleParameterSet();

}  // namespace fesbench::model
