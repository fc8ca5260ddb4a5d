#include "model/joint_model.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>

#include "model/units.h"

namespace fesbench::model {
namespace {

void RequireCurve(const PiecewiseLinear& curve, const char* field) {
  if (curve.empty()) {
    throw std::invalid_argument(std::string("joint model: ") + field + " is empty");
  }
}

void RequireFinite(double v, const char* field) {
  if (!std::isfinite(v)) {
    throw std::invalid_argument(std::string("joint model: ") + field + " is not finite");
  }
}

}  // namespace

CurvePairTable::CurvePairTable(const PiecewiseLinear& f, const PiecewiseLinear& g) {
  if (f.empty() || g.empty()) throw std::invalid_argument("CurvePairTable: empty curve");
  // A constant (one-breakpoint) curve adds no breakpoint, so tabulating a
  // curve with a constant gives bit-identical values to tabulating it alone.
  std::vector<double> x;
  if (f.size() > 1) x = f.x();
  if (g.size() > 1) x.insert(x.end(), g.x().begin(), g.x().end());
  std::sort(x.begin(), x.end());
  x.erase(std::unique(x.begin(), x.end()), x.end());
  if (x.empty()) x = {0.0, 1.0};  // two constants: one flat segment
  const std::size_t m = x.size();
  x_ = x;
  f_.resize(m);
  g_.resize(m);
  f_slope_.assign(m, 0.0);
  g_slope_.assign(m, 0.0);
  for (std::size_t i = 0; i < m; ++i) {
    f_[i] = f(x[i]);
    g_[i] = g(x[i]);
  }
  for (std::size_t i = 0; i + 1 < m; ++i) {
    const double dx = x[i + 1] - x[i];
    f_slope_[i] = (f_[i + 1] - f_[i]) / dx;  // Eq. 4.27 on each union segment
    g_slope_[i] = (g_[i + 1] - g_[i]) / dx;
  }
}

std::size_t CurvePairTable::SegmentBySearch(double x) const {
  return static_cast<std::size_t>(std::upper_bound(x_.begin(), x_.end(), x) - x_.begin()) - 1;
}

LinePairTable::LinePairTable(std::vector<double> b, const std::vector<double>& f,
                             const std::vector<double>& g, double g_left_slope,
                             double g_right_slope) {
  const std::size_t m = b.size();
  lines_.resize(m + 1);
  lines_.front() = {f.front(), 0.0, g.front() - g_left_slope * b.front(), g_left_slope};
  lines_.back() = {f.back(), 0.0, g.back() - g_right_slope * b.back(), g_right_slope};
  for (std::size_t i = 0; i + 1 < m; ++i) {
    const double dx = b[i + 1] - b[i];
    const double f1 = (f[i + 1] - f[i]) / dx, g1 = (g[i + 1] - g[i]) / dx;
    lines_[i + 1] = {f[i] - f1 * b[i], f1, g[i] - g1 * b[i], g1};
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  lower_.reserve(m + 2);
  lower_.push_back(nan);
  lower_.insert(lower_.end(), b.begin(), b.end());
  lower_.push_back(nan);
}

namespace {

// A gain of the model before its clamp at 0: linear between its kinks and
// beyond them with slopes (left, right): a piecewise-linear curve (held
// ends) or the line of the single-segment variant (Eqs. 5.1–5.2).
struct Gain {
  std::function<double(double)> at;
  std::vector<double> kinks;  // where the slope of max(gain, 0) may change
  double left_slope = 0.0, right_slope = 0.0;
};

Gain CurveGain(const PiecewiseLinear& c) {
  Gain g{[&c](double x) { return c(x); }, {}, 0.0, 0.0};
  if (c.size() > 1) g.kinks = c.x();
  const std::vector<double>& x = c.x();
  const std::vector<double>& y = c.y();
  for (std::size_t i = 0; i + 1 < x.size(); ++i) {
    if ((y[i] > 0.0 && y[i + 1] < 0.0) || (y[i] < 0.0 && y[i + 1] > 0.0)) {
      g.kinks.push_back(x[i] + y[i] * (x[i + 1] - x[i]) / (y[i] - y[i + 1]));  // 0 crossing
    }
  }
  return g;
}

Gain LineGain(double slope, double intercept) {
  Gain g{[slope, intercept](double x) { return slope * x + intercept; }, {}, slope, slope};
  if (slope != 0.0) g.kinks.push_back(-intercept / slope);  // 0 crossing
  return g;
}

// (scale·a(x), gain_scale·max(gain(x), 0)) as a LinePairTable on the
// breakpoints of a and the kinks of the gain (a constant curve adds none;
// none at all gives {0}).
LinePairTable ScaledTable(const PiecewiseLinear& a, double scale, const Gain& gain,
                          double gain_scale) {
  std::vector<double> x;
  if (a.size() > 1) x = a.x();
  x.insert(x.end(), gain.kinks.begin(), gain.kinks.end());
  std::sort(x.begin(), x.end());
  x.erase(std::unique(x.begin(), x.end()), x.end());
  if (x.empty()) x = {0.0};
  std::vector<double> f(x.size()), g(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    f[i] = scale * a(x[i]);
    g[i] = gain_scale * std::max(gain.at(x[i]), 0.0);
  }
  // Beyond the ends the gain keeps its sign: clamped there, or its slope.
  const double left = gain.at(x.front() - 1.0) > 0.0 ? gain_scale * gain.left_slope : 0.0;
  const double right = gain.at(x.back() + 1.0) > 0.0 ? gain_scale * gain.right_slope : 0.0;
  return LinePairTable(std::move(x), f, g, left, right);
}

}  // namespace

JointModel JointModel::FromParameters(const ParameterSet& params,
                                      std::optional<ModelKind> kind_override) {
  JointModel m;
  m.kind_ = kind_override.value_or(params.model);
  const double j = params.passive.inertia_kgm2;
  if (!std::isfinite(j) || !(j > 0.0)) {
    throw std::invalid_argument("joint model: passive.inertia_kgm2 must be finite and > 0");
  }
  const double scale = params.active.torque_scale_nm;
  if (!std::isfinite(scale) || scale < 0.0) {
    throw std::invalid_argument("joint model: active.torque_scale_nm must be finite and >= 0");
  }
  m.inertia_kgm2_ = j;
  m.accel_deg_per_nm_ = RadToDeg(1.0 / j);
  m.torque_scale_nm_ = scale;

  RequireCurve(params.passive.torque_velocity, "passive.torque_velocity");
  const PiecewiseLinear unit = PiecewiseLinear::Constant(1.0);
  // Tabulated gains (clamped at 0 when evaluated); 1 where the variant has none.
  const PiecewiseLinear* ata = &unit;
  const PiecewiseLinear* atv = &unit;
  switch (m.kind_) {
    case ModelKind::kFull:
      RequireCurve(params.active.torque_angle, "active.torque_angle");
      RequireCurve(params.active.torque_velocity, "active.torque_velocity");
      ata = &params.active.torque_angle;
      atv = &params.active.torque_velocity;
      break;
    case ModelKind::kTorqueGenerator:
      break;
    case ModelKind::kSingleSegment: {
      const SingleSegmentParams& s = params.single_segment;
      RequireFinite(s.a, "single_segment.a");
      RequireFinite(s.b, "single_segment.b");
      RequireFinite(s.c, "single_segment.c");
      RequireFinite(s.d, "single_segment.d");
      m.single_segment_ = s;
      break;
    }
    case ModelKind::kStaticGainPwlVelocity:
      RequireCurve(params.active.torque_velocity, "active.torque_velocity");
      atv = &params.active.torque_velocity;
      break;
    case ModelKind::kParametric: {
      const ParametricParams& p = params.parametric;
      RequireFinite(p.mgl_nm, "parametric.mgl_nm");
      RequireFinite(p.k1_nm, "parametric.k1_nm");
      RequireFinite(p.k2_per_rad, "parametric.k2_per_rad");
      RequireFinite(p.offset_nm, "parametric.offset_nm");
      RequireFinite(p.ata_peak_deg, "parametric.ata_peak_deg");
      RequireFinite(p.atv_slope_neg_per_deg_s, "parametric.atv_slope_neg_per_deg_s");
      RequireFinite(p.atv_slope_pos_per_deg_s, "parametric.atv_slope_pos_per_deg_s");
      if (!std::isfinite(p.ata_width_deg) || !(p.ata_width_deg > 0.0)) {
        throw std::invalid_argument("joint model: parametric.ata_width_deg must be finite and > 0");
      }
      m.parametric_ = p;
      break;
    }
  }
  if (m.kind_ == ModelKind::kParametric) {
    m.angle_table_ = CurvePairTable(unit, unit);  // τ_pta in closed form (Eq. 7.3)
  } else {
    RequireCurve(params.passive.torque_angle, "passive.torque_angle");
    m.angle_table_ = CurvePairTable(params.passive.torque_angle, *ata);
  }
  m.velocity_table_ = CurvePairTable(params.passive.torque_velocity, *atv);
  if (m.kind_ != ModelKind::kParametric) {
    const double k = m.accel_deg_per_nm_;
    const SingleSegmentParams& s = m.single_segment_;
    const bool line = m.kind_ == ModelKind::kSingleSegment;
    m.scaled_tables_ = true;
    m.scaled_angle_ = ScaledTable(params.passive.torque_angle, -k,
                                  line ? LineGain(s.a, s.b) : CurveGain(*ata), k * scale);
    m.scaled_velocity_ = ScaledTable(params.passive.torque_velocity, -k,
                                     line ? LineGain(s.c, s.d) : CurveGain(*atv), 1.0);
  }
  return m;
}

double JointModel::ParametricAcceleration(double angle_deg, double velocity_deg_s,
                                          double activation, Segments& segments,
                                          double motor_torque_nm) const {
  // J·θ̈ = τ_motor − τ_pta(θ) − τ_ptv(θ̇) − τ_act, θ̈ in rad/s² (§3.4, Eq. 3.16).
  double passive_nm = 0.0, gain_nm = 0.0;
  PassiveAndGain(angle_deg, velocity_deg_s, passive_nm, gain_nm, segments);
  return (motor_torque_nm - passive_nm - activation * gain_nm) * accel_deg_per_nm_;
}

double JointModel::PassiveAngleTorque(double angle_deg) const {
  if (kind_ == ModelKind::kParametric) {
    // Eq. 7.3, §7.4.4 (θ in radians) plus the §6.5 referencing constant.
    const ParametricParams& p = parametric_;
    const double th = DegToRad(angle_deg);
    return p.mgl_nm * std::sin(th) + p.k1_nm * std::exp(p.k2_per_rad * th) + p.offset_nm;
  }
  double pta = 0.0, gain = 0.0;
  angle_table_.Evaluate(angle_deg, pta, gain);
  return pta;
}

double JointModel::PassiveVelocityTorque(double velocity_deg_s) const {
  double ptv = 0.0, gain = 0.0;
  velocity_table_.Evaluate(velocity_deg_s, ptv, gain);
  return ptv;
}

double JointModel::AngleGain(double angle_deg) const {
  switch (kind_) {
    case ModelKind::kFull: {
      double pta = 0.0, gain = 0.0;
      angle_table_.Evaluate(angle_deg, pta, gain);
      return std::max(0.0, gain);
    }
    case ModelKind::kSingleSegment:  // Eq. 5.1
      return std::max(0.0, single_segment_.a * angle_deg + single_segment_.b);
    case ModelKind::kParametric: {
      // Gaussian normalised to 1 at 90° (§7.4.4, §6.7).
      const double mu = parametric_.ata_peak_deg;
      const double sigma = parametric_.ata_width_deg;
      const double d = angle_deg - mu;
      const double d90 = kReferenceAngleDeg - mu;
      return std::exp(-(d * d - d90 * d90) / (2.0 * sigma * sigma));
    }
    case ModelKind::kTorqueGenerator:
    case ModelKind::kStaticGainPwlVelocity:
      return 1.0;
  }
  return 1.0;
}

double JointModel::VelocityGain(double velocity_deg_s) const {
  switch (kind_) {
    case ModelKind::kFull:
    case ModelKind::kStaticGainPwlVelocity: {
      double ptv = 0.0, gain = 0.0;
      velocity_table_.Evaluate(velocity_deg_s, ptv, gain);
      return std::max(0.0, gain);
    }
    case ModelKind::kSingleSegment:  // Eq. 5.2
      return std::max(0.0, single_segment_.c * velocity_deg_s + single_segment_.d);
    case ModelKind::kParametric: {
      const double s = velocity_deg_s < 0.0 ? parametric_.atv_slope_neg_per_deg_s
                                            : parametric_.atv_slope_pos_per_deg_s;
      return std::max(0.0, 1.0 + s * velocity_deg_s);
    }
    case ModelKind::kTorqueGenerator:
      return 1.0;
  }
  return 1.0;
}

double JointModel::ActiveGain(double angle_deg, double velocity_deg_s) const {
  double passive = 0.0, gain = 0.0;
  Segments segments;
  PassiveAndGain(angle_deg, velocity_deg_s, passive, gain, segments);
  return gain;
}

}  // namespace fesbench::model
