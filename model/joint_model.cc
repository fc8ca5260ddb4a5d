#include "model/joint_model.h"

#include <algorithm>
#include <cmath>
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

FastCurve::FastCurve(const PiecewiseLinear& curve) : x_(curve.x()), y_(curve.y()) {
  if (x_.empty()) throw std::invalid_argument("FastCurve: empty curve");
  slope_.assign(x_.size(), 0.0);
  for (std::size_t i = 0; i + 1 < x_.size(); ++i) {
    slope_[i] = (y_[i + 1] - y_[i]) / (x_[i + 1] - x_[i]);  // Eq. 4.27
  }
}

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
  m.torque_scale_nm_ = scale;

  RequireCurve(params.passive.torque_velocity, "passive.torque_velocity");
  m.ptv_ = FastCurve(params.passive.torque_velocity);
  if (m.kind_ != ModelKind::kParametric) {
    RequireCurve(params.passive.torque_angle, "passive.torque_angle");
    m.pta_ = FastCurve(params.passive.torque_angle);
  }
  switch (m.kind_) {
    case ModelKind::kFull:
      RequireCurve(params.active.torque_angle, "active.torque_angle");
      RequireCurve(params.active.torque_velocity, "active.torque_velocity");
      m.ata_ = FastCurve(params.active.torque_angle);
      m.atv_ = FastCurve(params.active.torque_velocity);
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
      m.atv_ = FastCurve(params.active.torque_velocity);
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
  return m;
}

double JointModel::PassiveAngleTorque(double angle_deg) const {
  if (kind_ == ModelKind::kParametric) {
    // Eq. 7.3, §7.4.4 (θ in radians) plus the §6.5 referencing constant.
    const ParametricParams& p = parametric_;
    const double th = DegToRad(angle_deg);
    return p.mgl_nm * std::sin(th) + p.k1_nm * std::exp(p.k2_per_rad * th) + p.offset_nm;
  }
  return pta_(angle_deg);
}

double JointModel::AngleGain(double angle_deg) const {
  switch (kind_) {
    case ModelKind::kFull:
      return std::max(0.0, ata_(angle_deg));
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
    case ModelKind::kStaticGainPwlVelocity:
      return std::max(0.0, atv_(velocity_deg_s));
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

double JointModel::AccelerationDegS2(double angle_deg, double velocity_deg_s, double activation,
                                     double motor_torque_nm) const {
  // J·θ̈ = τ_motor − τ_pta(θ) − τ_ptv(θ̇) − τ_act, θ̈ in rad/s² (§3.4, Eq. 3.16).
  const double net_nm = motor_torque_nm - PassiveAngleTorque(angle_deg) -
                        PassiveVelocityTorque(velocity_deg_s) -
                        activation * ActiveGain(angle_deg, velocity_deg_s);
  return RadToDeg(net_nm / inertia_kgm2_);
}

}  // namespace fesbench::model
