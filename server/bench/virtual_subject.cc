#include "server/bench/virtual_subject.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "model/evaluation.h"
#include "model/identify_passive.h"
#include "model/units.h"

namespace fesbench::server {
namespace {

using model::DegToRad;
using model::kRadPerDeg;
using model::PiecewiseLinear;

// Uniform draws from the standardised mt19937_64 output (the standard
// library's distributions are implementation-defined; this is not).
class Draw {
 public:
  explicit Draw(std::uint64_t seed) : engine_(seed) {}
  double Uniform(double lo, double hi) {
    const double u = static_cast<double>(engine_() >> 11) * 0x1.0p-53;
    return lo + (hi - lo) * u;
  }

 private:
  std::mt19937_64 engine_;
};

// Winter (2009), Biomechanics and Motor Control of Human Movement, Table 4.1:
// leg-and-foot segment (knee to medial malleolus) mass fraction, centre of
// mass and proximal radius of gyration as fractions of segment length.
constexpr double kShankFootMassFraction = 0.061;
constexpr double kShankFootComFraction = 0.606;
constexpr double kShankFootGyrationFraction = 0.735;
constexpr double kShankOfHeight = 0.246;  // knee–ankle length / height.
constexpr double kBraceInertiaKgm2 = 0.02;

// A free-swing damping ratio drawn inside the central 80 % of the ranges'
// ζ, and the linear damping (N·m per deg/s) that gives it about the rest
// angle of `passive` with inertia j (Table 6.4, §6.9: k = dτ_pta/dθ there,
// τ_ptv still 0).
double DrawDampingNmPerDegS(Draw& draw, const SubjectRanges& ranges,
                            const model::PassiveParams& passive, double j) {
  const double zeta = draw.Uniform(ranges.min_zeta + 0.1 * (ranges.max_zeta - ranges.min_zeta),
                                   ranges.max_zeta - 0.1 * (ranges.max_zeta - ranges.min_zeta));
  const double rest_deg = model::PassiveRestAngle(passive);
  const double k_nm_per_rad = model::LinearisePassive(passive, rest_deg, 0.0).stiffness_nm_per_rad;
  return 2.0 * zeta * std::sqrt(k_nm_per_rad * j) * kRadPerDeg;
}

}  // namespace

double HangingAngleDeg(const Anthropometrics& anthropometrics) {
  return 90.0 - anthropometrics.thigh_elevation_deg;
}

double SteadyIsometricActiveTorqueNm(const model::ParameterSet& truth, double stim_ma,
                                     double angle_deg) {
  // Eqs. 3.18–3.19: C0·f_stim with C0 = f_ata(θ)·f_atv(0)·τ_scale; a steady
  // train settles at f_stim = R(u) (unit DC gain, docs/MODEL.md).
  const double r = std::max(0.0, truth.irc(stim_ma));
  return truth.active.torque_scale_nm * std::max(0.0, truth.active.torque_angle(angle_deg)) *
         std::max(0.0, truth.active.torque_velocity(0.0)) * r;
}

VirtualSubject DrawVirtualSubject(std::uint64_t seed, const SubjectRanges& ranges) {
  Draw draw(seed);
  VirtualSubject s;
  s.name = "virtual-" + std::to_string(seed);
  s.seed = seed;
  s.fidelity = Fidelity::Default();

  // Anthropometrics (§5.2.1: heights 5'2"–6'3").
  Anthropometrics& a = s.anthropometrics;
  a.body_mass_kg = draw.Uniform(50.0, 95.0);
  a.height_m = draw.Uniform(1.57, 1.91);
  a.shank_length_m = kShankOfHeight * a.height_m;
  a.accel_distance_m = draw.Uniform(0.24, 0.31);  // ≈ 11 in (§5.1)
  a.thigh_elevation_deg = draw.Uniform(4.0, 14.0);

  // Inertia of shank, foot and brace about the knee, with the ±10 % error of
  // the anthropometric estimate (§6.5, Table 6.3).
  const double m_kg = kShankFootMassFraction * a.body_mass_kg;
  const double l_m = a.shank_length_m;
  const double gyration_m = kShankFootGyrationFraction * l_m;
  double j = (m_kg * gyration_m * gyration_m + kBraceInertiaKgm2) * draw.Uniform(0.9, 1.1);
  j = std::clamp(j, ranges.min_inertia_kgm2, ranges.max_inertia_kgm2);
  const double mgl_nm = m_kg * model::kStandardGravity_m_s2 * kShankFootComFraction * l_m;
  const double hang_deg = HangingAngleDeg(a);

  // τ_pta: gravity (shank vertical at hang_deg) plus tissue stiffening near
  // full extension and deep flexion (Fig. 6-19, I-1).
  const double ext_nm = draw.Uniform(2.0, 6.0), ext_width = draw.Uniform(8.0, 15.0);
  const double flex_nm = draw.Uniform(1.0, 5.0), flex_width = draw.Uniform(10.0, 20.0);
  std::vector<double> angles, pta;
  for (int deg = 10; deg <= 110; deg += 10) {
    const double th = deg;
    angles.push_back(th);
    pta.push_back(mgl_nm * std::sin(DegToRad(th - hang_deg)) -
                  ext_nm * std::exp(-(th - 10.0) / ext_width) +
                  flex_nm * std::exp((th - 110.0) / flex_width));
  }
  model::PassiveParams passive;
  passive.inertia_kgm2 = j;
  passive.torque_angle = PiecewiseLinear(angles, pta);
  passive.torque_velocity = PiecewiseLinear::Constant(0.0);

  // τ_ptv: linear with slope b through ±20 deg/s so the linearised ζ is the
  // drawn one, mildly progressive and asymmetric beyond (Fig. 6-20, I-2).
  const double b_per_deg_s = DrawDampingNmPerDegS(draw, ranges, passive, j);
  const double grow_neg = draw.Uniform(0.0, 0.6), grow_pos = draw.Uniform(0.0, 0.6);
  const std::vector<double> vel = {-300, -150, -60, -20, 0, 20, 60, 150, 300};
  std::vector<double> ptv;
  for (double v : vel) {
    const double excess = std::max(0.0, std::abs(v) - 20.0) / 280.0;
    ptv.push_back(b_per_deg_s * v * (1.0 + (v < 0 ? grow_neg : grow_pos) * excess));
  }
  passive.torque_velocity = PiecewiseLinear(vel, ptv);
  s.truth.passive = model::ReferencePassive(passive);

  // Contraction dynamics: 3rd order, pole ≈ 25 s⁻¹ (§6.2).
  s.truth.model = model::ModelKind::kFull;
  s.truth.contraction.order = 3;
  s.truth.contraction.pole_per_s =
      ranges.nominal_pole_per_s * draw.Uniform(1.0 - ranges.pole_spread, 1.0 + ranges.pole_spread);

  // IRC: zero to threshold, smooth rise to saturation (§6.1, Fig. 6-1).
  s.max_tolerated_ma = draw.Uniform(ranges.min_max_tolerated_ma, ranges.max_max_tolerated_ma);
  s.threshold_ma = s.max_tolerated_ma * draw.Uniform(0.35, 0.6);
  const double sat_ma = s.max_tolerated_ma * draw.Uniform(1.0, 1.3);
  std::vector<double> irc_u = {0.0}, irc_r = {0.0};
  constexpr int kIrcPoints = 7;
  for (int i = 0; i < kIrcPoints; ++i) {
    const double x = static_cast<double>(i) / (kIrcPoints - 1);
    irc_u.push_back(s.threshold_ma + x * (sat_ma - s.threshold_ma));
    irc_r.push_back(x * x * (3.0 - 2.0 * x));
  }
  s.truth.irc = PiecewiseLinear(irc_u, irc_r);

  // Active curves: Gaussian f_ata peaking at 55–75° (Fig. I-3), Hill-like
  // f_atv: concentric hyperbola, eccentric rise to 1.3–1.6 (Fig. I-4).
  const double peak_deg = draw.Uniform(55.0, 75.0), width_deg = draw.Uniform(30.0, 45.0);
  const auto gauss = [&](double th) {
    return std::exp(-(th - peak_deg) * (th - peak_deg) / (2.0 * width_deg * width_deg));
  };
  std::vector<double> fata;
  for (double th : angles) fata.push_back(gauss(th) / gauss(model::kReferenceAngleDeg));
  const double v_max = draw.Uniform(700.0, 1000.0), kappa = draw.Uniform(0.6, 1.0);
  const double ecc_max = draw.Uniform(1.3, 1.6), ecc_half = draw.Uniform(100.0, 200.0);
  std::vector<double> atv_v, fatv;
  for (int v = -400; v <= 400; v += 100) {
    const double vd = v;
    atv_v.push_back(vd);
    if (v < 0) {
      fatv.push_back((1.0 + vd / v_max) / (1.0 - vd / (kappa * v_max)));
    } else {
      fatv.push_back(1.0 + (ecc_max - 1.0) * vd / (vd + ecc_half));
    }
  }
  const double max_torque_nm = draw.Uniform(ranges.min_max_torque_nm, ranges.max_max_torque_nm);
  s.truth.active.torque_angle = PiecewiseLinear(angles, fata);
  s.truth.active.torque_velocity = PiecewiseLinear(atv_v, fatv);
  s.truth.active.torque_scale_nm = max_torque_nm / s.truth.irc(s.max_tolerated_ma);
  s.truth.provenance.passive_method = "virtual_subject";
  return s;
}

std::string_view SubjectFamilyName(SubjectFamily family) {
  switch (family) {
    case SubjectFamily::kAnalytic:
      return "analytic";
    case SubjectFamily::kPlateau:
      return "plateau";
    case SubjectFamily::kThesis:
      break;
  }
  return "thesis";
}

std::optional<SubjectFamily> SubjectFamilyFromName(std::string_view name) {
  if (name == "thesis") return SubjectFamily::kThesis;
  if (name == "analytic") return SubjectFamily::kAnalytic;
  if (name == "plateau") return SubjectFamily::kPlateau;
  return std::nullopt;
}

VirtualSubject DrawSubject(std::uint64_t seed, SubjectFamily family, const SubjectRanges& ranges) {
  switch (family) {
    case SubjectFamily::kAnalytic:
      return DrawAnalyticSubject(seed, ranges);
    case SubjectFamily::kPlateau:
      return DrawPlateauSubject(seed, ranges);
    case SubjectFamily::kThesis:
      break;
  }
  return DrawVirtualSubject(seed, ranges);
}

namespace {

// Anthropometrics and J (Eq. 4.13 plus the brace, ±10 %) of the analytic
// and plateau families: height and body-mass index uniform in their
// ranges, redrawn until J is in range so the body measures and J always
// agree; then the accelerometer's distance and the thigh's elevation.
// Returns J. Ranges whose inertia no body of the family reaches in 1000
// draws get the last J clamped into them, as DrawVirtualSubject does.
double DrawBodyAndInertia(Draw& draw, const SubjectRanges& ranges,
                          std::pair<double, double> height_m, std::pair<double, double> bmi,
                          Anthropometrics& a) {
  double j = 0.0;
  for (int attempt = 0;; ++attempt) {
    a.height_m = draw.Uniform(height_m.first, height_m.second);
    a.body_mass_kg = draw.Uniform(bmi.first, bmi.second) * a.height_m * a.height_m;
    a.shank_length_m = kShankOfHeight * a.height_m;
    j = (model::AnthropometricInertia(a.body_mass_kg, a.shank_length_m) + kBraceInertiaKgm2) *
        draw.Uniform(0.9, 1.1);
    if (j >= ranges.min_inertia_kgm2 && j <= ranges.max_inertia_kgm2) break;
    if (attempt == 1000) {
      j = std::clamp(j, ranges.min_inertia_kgm2, ranges.max_inertia_kgm2);
      break;
    }
  }
  a.accel_distance_m = draw.Uniform(0.24, 0.31);  // ≈ 11 in (§5.1)
  a.thigh_elevation_deg = draw.Uniform(4.0, 14.0);
  return j;
}

}  // namespace

VirtualSubject DrawAnalyticSubject(std::uint64_t seed, const SubjectRanges& ranges) {
  // Its own stream: the analytic leg of seed N shares nothing with the
  // thesis-family leg of seed N.
  Draw draw(seed ^ 0x9E3779B97F4A7C15ULL);
  VirtualSubject s;
  s.name = "analytic-" + std::to_string(seed);
  s.seed = seed;
  s.fidelity = Fidelity::Default();

  Anthropometrics& a = s.anthropometrics;
  const double j = DrawBodyAndInertia(draw, ranges, {1.55, 1.93}, {19.0, 29.0}, a);
  const double mgl_nm = kShankFootMassFraction * a.body_mass_kg * model::kStandardGravity_m_s2 *
                        kShankFootComFraction * a.shank_length_m;
  const double hang_deg = HangingAngleDeg(a);

  // τ_pta: gravity plus exponential end-range stiffness (Eq. 7.3, §7.4.4),
  // each end term at most kEndCapNm at the ends of the sampled range.
  constexpr double kEndCapNm = 50.0, kMinDeg = 0.0, kMaxDeg = 120.0;
  constexpr int kPoints = 41;
  const double hi_deg = draw.Uniform(100.0, 115.0), k1 = draw.Uniform(0.5, 3.0);
  const double k2 =
      std::min(draw.Uniform(0.06, 0.15), std::log(kEndCapNm / k1) / (kMaxDeg - hi_deg));
  const double lo_deg = draw.Uniform(5.0, 20.0), k3 = draw.Uniform(0.5, 4.0);
  const double k4 =
      std::min(draw.Uniform(0.08, 0.2), std::log(kEndCapNm / k3) / (lo_deg - kMinDeg));
  std::vector<double> angles, pta;
  for (int i = 0; i < kPoints; ++i) {
    const double th = kMinDeg + (kMaxDeg - kMinDeg) * i / (kPoints - 1);
    angles.push_back(th);
    pta.push_back(mgl_nm * std::sin(DegToRad(th - hang_deg)) + k1 * std::exp(k2 * (th - hi_deg)) -
                  k3 * std::exp(-k4 * (th - lo_deg)));
  }
  model::PassiveParams passive;
  passive.inertia_kgm2 = j;
  passive.torque_angle = PiecewiseLinear(angles, pta);
  passive.torque_velocity = PiecewiseLinear::Constant(0.0);

  // τ_ptv: two lines through 0 with different slopes for extension (v < 0)
  // and flexion (v > 0) velocity; their mean (the central slope at 0) gives
  // the drawn linearised ζ about the rest angle (Table 6.4, §6.9).
  const double b_mean = DrawDampingNmPerDegS(draw, ranges, passive, j);
  const double ratio = draw.Uniform(1.3, 2.5);
  const bool flexion_stiffer = draw.Uniform(0.0, 1.0) < 0.5;
  const double b_small = 2.0 * b_mean / (1.0 + ratio), b_large = ratio * b_small;
  const double b_neg = flexion_stiffer ? b_small : b_large;
  const double b_pos = flexion_stiffer ? b_large : b_small;
  constexpr double kMaxVel = 400.0;
  std::vector<double> vel, ptv;
  for (int i = 0; i < kPoints; ++i) {
    const double v = -kMaxVel + 2.0 * kMaxVel * i / (kPoints - 1);
    vel.push_back(v);
    ptv.push_back(v * (v < 0.0 ? b_neg : b_pos));
  }
  passive.torque_velocity = PiecewiseLinear(vel, ptv);
  s.truth.passive = model::ReferencePassive(passive);

  // Contraction dynamics: 3rd order, pole 20–30 s⁻¹ (§6.2).
  s.truth.model = model::ModelKind::kFull;
  s.truth.contraction.order = 3;
  s.truth.contraction.pole_per_s = ranges.nominal_pole_per_s * draw.Uniform(0.8, 1.2);

  // IRC: zero to threshold, then (1 − e^{−a·x²}) / (1 − e^{−a}) to saturation.
  s.max_tolerated_ma = draw.Uniform(ranges.min_max_tolerated_ma, ranges.max_max_tolerated_ma);
  s.threshold_ma = s.max_tolerated_ma * draw.Uniform(0.3, 0.55);
  const double sat_ma = s.max_tolerated_ma * draw.Uniform(1.0, 1.3);
  const double irc_a = draw.Uniform(2.0, 5.0);
  std::vector<double> irc_u = {0.0}, irc_r = {0.0};
  constexpr int kIrcPoints = 13;
  for (int i = 0; i < kIrcPoints; ++i) {
    const double x = static_cast<double>(i) / (kIrcPoints - 1);
    irc_u.push_back(s.threshold_ma + x * (sat_ma - s.threshold_ma));
    irc_r.push_back((1.0 - std::exp(-irc_a * x * x)) / (1.0 - std::exp(-irc_a)));
  }
  s.truth.irc = PiecewiseLinear(irc_u, irc_r);

  // f_ata: a Gaussian outside the thesis generator's centres and widths,
  // keeping f_ata(90°) ≥ 0.3 of the peak (the reference of §6.7).
  const bool flexed = draw.Uniform(0.0, 1.0) < 0.5;
  const double centre_deg = flexed ? draw.Uniform(78.0, 95.0) : draw.Uniform(40.0, 52.0);
  const double min_width =
      std::abs(model::kReferenceAngleDeg - centre_deg) / std::sqrt(2.0 * std::log(1.0 / 0.3));
  const bool narrow = draw.Uniform(0.0, 1.0) < 0.5 && min_width <= 28.0;
  const double width_deg = narrow ? draw.Uniform(std::max(20.0, min_width), 30.0)
                                  : draw.Uniform(std::max(46.0, min_width), 60.0);
  std::vector<double> fata;
  for (double th : angles) {
    fata.push_back(
        std::exp(-(th - centre_deg) * (th - centre_deg) / (2.0 * width_deg * width_deg)));
  }
  // f_atv: 1 + A·tanh(v/v0), its own A and v0 on each side of 0.
  const double a_con = draw.Uniform(0.4, 0.85), v_con = draw.Uniform(120.0, 400.0);
  const double a_ecc = draw.Uniform(0.2, 0.6), v_ecc = draw.Uniform(60.0, 200.0);
  std::vector<double> fatv;
  for (double v : vel) {
    fatv.push_back(v < 0.0 ? 1.0 + a_con * std::tanh(v / v_con)
                           : 1.0 + a_ecc * std::tanh(v / v_ecc));
  }
  // Max isometric torque at the Gaussian's peak (1 there) and max tolerated.
  const double max_torque_nm = draw.Uniform(ranges.min_max_torque_nm, ranges.max_max_torque_nm);
  model::ActiveParams active;
  active.torque_angle = PiecewiseLinear(angles, fata);
  active.torque_velocity = PiecewiseLinear(vel, fatv);
  active.torque_scale_nm = max_torque_nm / s.truth.irc(s.max_tolerated_ma);
  s.truth.active = model::NormaliseActive(active);
  s.truth.provenance.passive_method = "virtual_subject";
  return s;
}

VirtualSubject DrawPlateauSubject(std::uint64_t seed, const SubjectRanges& ranges) {
  // Its own stream, unrelated to the other families' seed N.
  Draw draw(seed ^ 0xD1B54A32D192ED03ULL);
  VirtualSubject s;
  s.name = "plateau-" + std::to_string(seed);
  s.seed = seed;
  // Strong post-tetanic potentiation and slow recovery from fatigue (§3.3).
  s.fidelity = Fidelity::Default();
  s.fidelity.potentiation_max = draw.Uniform(0.6, 1.0);
  s.fidelity.fatigue_recovery_s = draw.Uniform(90.0, 180.0);

  Anthropometrics& a = s.anthropometrics;
  const double j = DrawBodyAndInertia(draw, ranges, {1.50, 1.95}, {18.0, 32.0}, a);
  const double mgl_nm = kShankFootMassFraction * a.body_mass_kg * model::kStandardGravity_m_s2 *
                        kShankFootComFraction * a.shank_length_m;
  const double hang_deg = HangingAngleDeg(a);

  // τ_pta: gravity plus steep exponential stiffness at both ends (Eq. 7.3,
  // §7.4.4, with an extension-end term): each end term is 20–50 N·m at the
  // bench's stop (10°, 110°) and falls by e every 3–8° inside it.
  constexpr double kLoStopDeg = 10.0, kHiStopDeg = 110.0;
  constexpr int kPoints = 61;  // every 2° over 0–120°.
  const double hi_nm = draw.Uniform(20.0, 50.0), hi_width = draw.Uniform(3.0, 8.0);
  const double lo_nm = draw.Uniform(20.0, 50.0), lo_width = draw.Uniform(3.0, 8.0);
  std::vector<double> angles, pta;
  for (int i = 0; i < kPoints; ++i) {
    const double th = 120.0 * i / (kPoints - 1);
    angles.push_back(th);
    pta.push_back(mgl_nm * std::sin(DegToRad(th - hang_deg)) +
                  hi_nm * std::exp((th - kHiStopDeg) / hi_width) -
                  lo_nm * std::exp((kLoStopDeg - th) / lo_width));
  }
  model::PassiveParams passive;
  passive.inertia_kgm2 = j;
  passive.torque_angle = PiecewiseLinear(angles, pta);
  passive.torque_velocity = PiecewiseLinear::Constant(0.0);

  // τ_ptv: b·v·(1 + g·(v/200)²), progressive with speed (g 0–0.5); b gives
  // the drawn linearised ζ about the rest angle (Table 6.4, §6.9).
  const double b = DrawDampingNmPerDegS(draw, ranges, passive, j);
  const double grow = draw.Uniform(0.0, 0.5);
  constexpr double kMaxVel = 400.0;
  constexpr int kVelPoints = 41;
  std::vector<double> vel, ptv;
  for (int i = 0; i < kVelPoints; ++i) {
    const double v = -kMaxVel + 2.0 * kMaxVel * i / (kVelPoints - 1);
    vel.push_back(v);
    ptv.push_back(b * v * (1.0 + grow * (v / 200.0) * (v / 200.0)));
  }
  passive.torque_velocity = PiecewiseLinear(vel, ptv);
  s.truth.passive = model::ReferencePassive(passive);

  // Contraction dynamics: 3rd order, pole 20–30 s⁻¹ (§6.2).
  s.truth.model = model::ModelKind::kFull;
  s.truth.contraction.order = 3;
  s.truth.contraction.pole_per_s = ranges.nominal_pole_per_s * draw.Uniform(0.8, 1.2);

  // IRC: zero to threshold, then a concave rise p·(1 − (1 − x)^n) that
  // plateaus at p = 0.6–0.9 of full activation from 70–90 % of the max
  // tolerated amplitude on: the top of the tolerable range recruits no more.
  s.max_tolerated_ma = draw.Uniform(ranges.min_max_tolerated_ma, ranges.max_max_tolerated_ma);
  s.threshold_ma = s.max_tolerated_ma * draw.Uniform(0.3, 0.5);
  const double plateau_ma = s.max_tolerated_ma * draw.Uniform(0.7, 0.9);
  const double plateau = draw.Uniform(0.6, 0.9), irc_n = draw.Uniform(2.0, 3.0);
  std::vector<double> irc_u = {0.0}, irc_r = {0.0};
  constexpr int kIrcPoints = 13;
  for (int i = 0; i < kIrcPoints; ++i) {
    const double x = static_cast<double>(i) / (kIrcPoints - 1);
    irc_u.push_back(s.threshold_ma + x * (plateau_ma - s.threshold_ma));
    irc_r.push_back(plateau * (1.0 - std::pow(1.0 - x, irc_n)));
  }
  irc_u.push_back(std::max(s.max_tolerated_ma, plateau_ma) * 1.5);
  irc_r.push_back(plateau);
  s.truth.irc = PiecewiseLinear(irc_u, irc_r);

  // f_ata: a Gaussian centred at 55–85°, width 30–50°; f_atv: concentric
  // 1 + A·tanh(v/v0) (A 0.5–0.8, v0 150–350 deg/s), eccentric rise to
  // 1.2–1.5 by a hyperbola of half-speed 80–200 deg/s.
  const double centre_deg = draw.Uniform(55.0, 85.0), width_deg = draw.Uniform(30.0, 50.0);
  std::vector<double> fata;
  for (double th : angles) {
    fata.push_back(
        std::exp(-(th - centre_deg) * (th - centre_deg) / (2.0 * width_deg * width_deg)));
  }
  const double a_con = draw.Uniform(0.5, 0.8), v_con = draw.Uniform(150.0, 350.0);
  const double ecc_max = draw.Uniform(1.2, 1.5), ecc_half = draw.Uniform(80.0, 200.0);
  std::vector<double> fatv;
  for (double v : vel) {
    fatv.push_back(v < 0.0 ? 1.0 + a_con * std::tanh(v / v_con)
                           : 1.0 + (ecc_max - 1.0) * v / (v + ecc_half));
  }
  // Max isometric torque (at the Gaussian's peak, max tolerated) 10–60 N·m.
  const double max_torque_nm = draw.Uniform(ranges.min_max_torque_nm, ranges.max_max_torque_nm);
  model::ActiveParams active;
  active.torque_angle = PiecewiseLinear(angles, fata);
  active.torque_velocity = PiecewiseLinear(vel, fatv);
  active.torque_scale_nm = max_torque_nm / s.truth.irc(s.max_tolerated_ma);
  s.truth.active = model::NormaliseActive(active);
  s.truth.provenance.passive_method = "virtual_subject";
  return s;
}

}  // namespace fesbench::server
