#include "model/parameter_set.h"

#include <array>
#include <cmath>
#include <stdexcept>

#include "model/units.h"

namespace fesbench::model {
namespace {

constexpr std::array<std::pair<ModelKind, std::string_view>, 5> kModelNames = {{
    {ModelKind::kFull, "full"},
    {ModelKind::kTorqueGenerator, "torque_generator"},
    {ModelKind::kSingleSegment, "single_segment"},
    {ModelKind::kStaticGainPwlVelocity, "static_gain_pwl_velocity"},
    {ModelKind::kParametric, "parametric"},
}};

}  // namespace

std::string_view ModelKindName(ModelKind kind) {
  for (const auto& [k, name] : kModelNames) {
    if (k == kind) return name;
  }
  return "unknown";
}

std::optional<ModelKind> ParseModelKind(std::string_view name) {
  for (const auto& [k, n] : kModelNames) {
    if (n == name) return k;
  }
  return std::nullopt;
}

const std::vector<ModelKind>& AllModelKinds() {
  static const std::vector<ModelKind> kinds = [] {
    std::vector<ModelKind> v;
    for (const auto& entry : kModelNames) v.push_back(entry.first);
    return v;
  }();
  return kinds;
}

PassiveParams ReferencePassive(const PassiveParams& passive) {
  if (passive.torque_angle.empty() || passive.torque_velocity.empty()) {
    throw std::invalid_argument("ReferencePassive: passive curves must not be empty");
  }
  // §6.5: a constant moved from τ_pta into τ_ptv leaves their sum unchanged.
  const double c = passive.torque_angle(kReferenceAngleDeg);
  PassiveParams out = passive;
  out.torque_angle = passive.torque_angle.Shifted(-c);
  out.torque_velocity = passive.torque_velocity.Shifted(c);
  return out;
}

ActiveParams NormaliseActive(const ActiveParams& active) {
  if (active.torque_angle.empty() || active.torque_velocity.empty()) {
    throw std::invalid_argument("NormaliseActive: active curves must not be empty");
  }
  const double ga = active.torque_angle(kReferenceAngleDeg);
  const double gv = active.torque_velocity(kReferenceVelocityDegS);
  if (!(ga > 0.0) || !(gv > 0.0)) {
    throw std::invalid_argument(
        "NormaliseActive: f_ata(90°) and f_atv(0) must be positive to normalise");
  }
  ActiveParams out = active;
  out.torque_angle = active.torque_angle.Scaled(1.0 / ga);
  out.torque_velocity = active.torque_velocity.Scaled(1.0 / gv);
  out.torque_scale_nm = active.torque_scale_nm * ga * gv;
  return out;
}

ParameterSet ExampleParameterSet() {
  ParameterSet p;
  p.model = ModelKind::kFull;
  p.irc = PiecewiseLinear({0, 20, 25, 30, 35, 40, 45}, {0, 0, 0.1, 0.3, 0.6, 0.85, 1.0});
  p.contraction = {3, 25.0};

  // Gravity on a shank of m·g·l ≈ 8.6 N·m hanging at 81° (Table 6.4), plus
  // tissue stiffness rising towards both ends of the range.
  std::vector<double> angles, pta;
  for (int a = 10; a <= 110; a += 10) {
    const double th = a;
    angles.push_back(th);
    pta.push_back(8.6 * std::sin(DegToRad(th - 81.0)) - 4.0 * std::exp(-(th - 10.0) / 12.0) +
                  3.0 * std::exp((th - 110.0) / 15.0));
  }
  const std::vector<double> vel = {-400, -200, -100, -50, 0, 50, 100, 200, 400};
  std::vector<double> ptv;
  for (double v : vel) ptv.push_back(0.005 * v + 0.15 * std::tanh(v / 20.0));
  p.passive.inertia_kgm2 = 0.36;
  p.passive.torque_angle = PiecewiseLinear(angles, pta);
  p.passive.torque_velocity = PiecewiseLinear(vel, ptv);
  p.passive = ReferencePassive(p.passive);

  std::vector<double> fata;
  const auto gauss = [](double th) { return std::exp(-(th - 65.0) * (th - 65.0) / (2 * 35.0 * 35.0)); };
  for (double th : angles) fata.push_back(gauss(th) / gauss(kReferenceAngleDeg));
  p.active.torque_scale_nm = 40.0;
  p.active.torque_angle = PiecewiseLinear(angles, fata);
  p.active.torque_velocity = PiecewiseLinear({-400, -300, -200, -100, 0, 100, 200, 300, 400},
                                             {0.45, 0.58, 0.72, 0.86, 1.0, 1.1, 1.18, 1.24, 1.28});
  return p;
}

}  // namespace fesbench::model
