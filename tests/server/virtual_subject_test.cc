#include "server/bench/virtual_subject.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "api/parameter_set_json.h"
#include "api/virtual_subject.h"
#include "model/evaluation.h"
#include "model/units.h"

namespace fesbench::server {
namespace {

TEST(VirtualSubject, DrawnSubjectsAreInsideTheThesisRanges) {
  const SubjectRanges r;
  for (std::uint64_t seed = 1; seed <= 200; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const VirtualSubject s = DrawVirtualSubject(seed);
    ASSERT_TRUE(ValidateVirtualSubject(s).ok()) << ValidateVirtualSubject(s).ToString();
    EXPECT_GE(s.truth.passive.inertia_kgm2, 0.17);
    EXPECT_LE(s.truth.passive.inertia_kgm2, 0.70);
    EXPECT_GE(s.max_tolerated_ma, 30.0);
    EXPECT_LE(s.max_tolerated_ma, 60.0);
    EXPECT_LT(s.threshold_ma, s.max_tolerated_ma);
    EXPECT_EQ(s.truth.irc(s.threshold_ma), 0.0);
    EXPECT_GT(s.truth.irc(s.threshold_ma + 1.0), 0.0);
    const double max_torque = SteadyIsometricActiveTorqueNm(s.truth, s.max_tolerated_ma, 90.0);
    EXPECT_GE(max_torque, 10.0 - 1e-9);
    EXPECT_LE(max_torque, 60.0 + 1e-9);
    EXPECT_EQ(s.truth.contraction.order, 3);
    EXPECT_NEAR(s.truth.contraction.pole_per_s, 25.0, 2.5 + 1e-9);
    // ζ from the linearised passive curves (Table 6.4), computed here
    // independently: k and b as central differences about the rest angle.
    const auto& p = s.truth.passive;
    const double ptv0 = p.torque_velocity(0.0);
    double lo = 10.0, hi = 110.0;
    ASSERT_LT(p.torque_angle(lo) + ptv0, 0.0);
    ASSERT_GT(p.torque_angle(hi) + ptv0, 0.0);
    for (int i = 0; i < 60; ++i) {
      const double mid = 0.5 * (lo + hi);
      (p.torque_angle(mid) + ptv0 < 0.0 ? lo : hi) = mid;
    }
    const double k = (p.torque_angle(lo + 0.5) - p.torque_angle(lo - 0.5)) * model::kDegPerRad;
    const double b = (p.torque_velocity(0.5) - p.torque_velocity(-0.5)) * model::kDegPerRad;
    const double zeta = b / (2.0 * std::sqrt(k * p.inertia_kgm2));
    EXPECT_GE(zeta, 0.02);
    EXPECT_LE(zeta, 0.15);
    const double rest_deg = model::PassiveRestAngle(p);
    EXPECT_NEAR(rest_deg, lo, 1e-6);
    EXPECT_NEAR(model::LinearisePassive(p, rest_deg, 0.0).damping_ratio, zeta, 0.01);
    // The leg hangs near 80–90° (reclined subject, §5.2.1, Table 6.4).
    EXPECT_GT(lo, 70.0);
    EXPECT_LT(lo, 92.0);
    // Referenced per §6.5.
    EXPECT_NEAR(p.torque_angle(90.0), 0.0, 1e-9);
  }
}

TEST(VirtualSubject, SameSeedSameSubjectOtherSeedOtherSubject) {
  EXPECT_EQ(DrawVirtualSubject(42), DrawVirtualSubject(42));
  EXPECT_NE(DrawVirtualSubject(42).truth, DrawVirtualSubject(43).truth);
}

// Analytic family (DrawAnalyticSubject): every draw within the plausible
// ranges of a human knee, checked on the sampled truth curves.
TEST(AnalyticSubject, DrawsAreInsideThePlausibleRanges) {
  double min_centre = 1e9, max_centre = -1e9;
  int flexion_stiffer = 0;
  for (std::uint64_t seed = 1; seed <= 200; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const VirtualSubject s = DrawAnalyticSubject(seed);
    ASSERT_TRUE(ValidateVirtualSubject(s).ok()) << ValidateVirtualSubject(s).ToString();
    EXPECT_EQ(s.fidelity, Fidelity::Default());
    const auto& p = s.truth.passive;
    // J and the body measures agree: Eq. 4.13 plus the 0.02 kg·m² brace, ±10 %.
    const auto& a = s.anthropometrics;
    const double eq_4_13 = 0.061 * a.body_mass_kg * std::pow(0.735 * a.shank_length_m, 2);
    EXPECT_GE(p.inertia_kgm2, 0.9 * (eq_4_13 + 0.02) - 1e-12);
    EXPECT_LE(p.inertia_kgm2, 1.1 * (eq_4_13 + 0.02) + 1e-12);
    EXPECT_NEAR(a.shank_length_m, 0.246 * a.height_m, 1e-12);
    const double bmi = a.body_mass_kg / (a.height_m * a.height_m);
    EXPECT_GE(bmi, 19.0);
    EXPECT_LE(bmi, 29.0);
    EXPECT_GE(p.inertia_kgm2, 0.17);
    EXPECT_LE(p.inertia_kgm2, 0.70);
    EXPECT_GE(s.max_tolerated_ma, 30.0);
    EXPECT_LE(s.max_tolerated_ma, 60.0);
    EXPECT_GT(s.threshold_ma, 0.0);
    EXPECT_LT(s.threshold_ma, s.max_tolerated_ma);
    EXPECT_EQ(s.truth.irc(s.threshold_ma), 0.0);
    EXPECT_GT(s.truth.irc(s.threshold_ma + 1.0), 0.0);
    EXPECT_LE(s.truth.irc(100.0), 1.0 + 1e-12);
    // Max isometric torque over the range at max tolerated: 10–60 N·m (the
    // sampled peak is at most 1 % below the analytic one).
    double max_torque = 0.0, peak_deg = 0.0;
    for (double th = 0.0; th <= 120.0; th += 0.5) {
      const double t = SteadyIsometricActiveTorqueNm(s.truth, s.max_tolerated_ma, th);
      if (t > max_torque) max_torque = t, peak_deg = th;
    }
    EXPECT_GE(max_torque, 0.99 * 10.0);
    EXPECT_LE(max_torque, 60.0 + 1e-9);
    // f_ata: other centres than the thesis generator's 55–75°; ≥ 0 everywhere.
    EXPECT_TRUE((peak_deg >= 38.0 && peak_deg <= 54.0) || (peak_deg >= 76.0 && peak_deg <= 97.0))
        << peak_deg;
    min_centre = std::min(min_centre, peak_deg);
    max_centre = std::max(max_centre, peak_deg);
    EXPECT_NEAR(s.truth.active.torque_angle(90.0), 1.0, 1e-9);  // §6.7
    for (double th = 0.0; th <= 120.0; th += 3.0) EXPECT_GE(s.truth.active.torque_angle(th), 0.0);
    // f_atv: tanh on each side, 1 at 0, positive, rising with velocity.
    const auto& fatv = s.truth.active.torque_velocity;
    EXPECT_NEAR(fatv(0.0), 1.0, 1e-9);
    for (double v = -400.0; v < 400.0; v += 20.0) {
      EXPECT_GT(fatv(v), 0.1);
      EXPECT_LT(fatv(v), fatv(v + 20.0));
    }
    EXPECT_LT(fatv(-400.0), 1.0 - 0.4 * std::tanh(1.0) + 1e-9);  // A ≥ 0.4, v0 ≤ 400
    EXPECT_GT(fatv(400.0), 1.15);
    EXPECT_EQ(s.truth.contraction.order, 3);
    EXPECT_GE(s.truth.contraction.pole_per_s, 20.0);
    EXPECT_LE(s.truth.contraction.pole_per_s, 30.0);
    // A stable rest angle in 10–110° with ζ in range (Table 6.4).
    const double rest_deg = model::PassiveRestAngle(p);
    EXPECT_GE(rest_deg, 10.0);
    EXPECT_LE(rest_deg, 110.0);
    const model::PassiveLinearisation lin = model::LinearisePassive(p, rest_deg, 0.0);
    EXPECT_GT(lin.stiffness_nm_per_rad, 0.0);
    EXPECT_GE(lin.damping_ratio, 0.02);
    EXPECT_LE(lin.damping_ratio, 0.15);
    // Damping: two lines with different slopes (ratio 1.3–2.5).
    const double b_ext = (p.torque_velocity(0.0) - p.torque_velocity(-200.0)) / 200.0;
    const double b_flex = (p.torque_velocity(200.0) - p.torque_velocity(0.0)) / 200.0;
    EXPECT_GT(b_ext, 0.0);
    EXPECT_GT(b_flex, 0.0);
    const double ratio = std::max(b_ext, b_flex) / std::min(b_ext, b_flex);
    EXPECT_GE(ratio, 1.3 - 1e-9);
    EXPECT_LE(ratio, 2.5 + 1e-9);
    if (b_flex > b_ext) ++flexion_stiffer;
    // τ_pta: gravity plus stiffening at both ends (each end segment steeper
    // than gravity's over it) and bounded; referenced (§6.5).
    const double mgl = 0.061 * a.body_mass_kg * 9.80665 * 0.606 * a.shank_length_m;
    const double hang = HangingAngleDeg(a);
    const auto gravity_chord = [&](double th0, double th1) {
      return mgl * (std::sin(model::DegToRad(th1 - hang)) - std::sin(model::DegToRad(th0 - hang))) /
             (th1 - th0);
    };
    EXPECT_GT((p.torque_angle(3.0) - p.torque_angle(0.0)) / 3.0, gravity_chord(0.0, 3.0));
    EXPECT_GT((p.torque_angle(120.0) - p.torque_angle(117.0)) / 3.0, gravity_chord(117.0, 120.0));
    EXPECT_LT(std::abs(p.torque_angle(0.0)), 2.0 * mgl + 60.0);
    EXPECT_LT(std::abs(p.torque_angle(120.0)), 2.0 * mgl + 60.0);
    EXPECT_NEAR(p.torque_angle(90.0), 0.0, 1e-9);
    EXPECT_EQ(p.torque_angle.x().size(), 41u);
    EXPECT_EQ(p.torque_velocity.x().size(), 41u);
  }
  // Both branches of the centre and of the asymmetry occur.
  EXPECT_LT(min_centre, 55.0);
  EXPECT_GT(max_centre, 75.0);
  EXPECT_GT(flexion_stiffer, 40);
  EXPECT_LT(flexion_stiffer, 160);
}

TEST(AnalyticSubject, SeededAndIndependentOfTheThesisFamily) {
  EXPECT_EQ(DrawAnalyticSubject(42), DrawAnalyticSubject(42));
  EXPECT_NE(DrawAnalyticSubject(42).truth, DrawAnalyticSubject(43).truth);
  EXPECT_NE(DrawAnalyticSubject(42).anthropometrics, DrawVirtualSubject(42).anthropometrics);
  EXPECT_EQ(DrawAnalyticSubject(42).name, "analytic-42");
  EXPECT_EQ(DrawSubject(42, SubjectFamily::kAnalytic), DrawAnalyticSubject(42));
  EXPECT_EQ(DrawSubject(42, SubjectFamily::kThesis), DrawVirtualSubject(42));
  EXPECT_EQ(SubjectFamilyFromName("analytic"), SubjectFamily::kAnalytic);
  EXPECT_EQ(SubjectFamilyFromName("thesis"), SubjectFamily::kThesis);
  EXPECT_EQ(SubjectFamilyFromName("Analytic"), std::nullopt);
  EXPECT_EQ(SubjectFamilyName(SubjectFamily::kAnalytic), "analytic");
  // The truth survives the JSON the server sends.
  const VirtualSubject s = DrawAnalyticSubject(7);
  const auto back = VirtualSubjectFromJson(nlohmann::json::parse(VirtualSubjectToJson(s).dump()));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(*back, s);
}

// Ranges whose inertia no drawn body reaches (J of Eq. 4.13 stays below
// 1 kg·m² for these heights and masses): J is clamped into them, as the
// thesis family's is, and the subject is still a valid one.
TEST(AnalyticSubject, AnInertiaRangeNoBodyReachesClampsJ) {
  SubjectRanges r;
  r.min_inertia_kgm2 = 3.0;
  r.max_inertia_kgm2 = 3.5;
  for (SubjectFamily family : {SubjectFamily::kAnalytic, SubjectFamily::kPlateau}) {
    const VirtualSubject s = DrawSubject(5, family, r);
    EXPECT_EQ(s.truth.passive.inertia_kgm2, 3.0) << SubjectFamilyName(family);
    EXPECT_TRUE(ValidateVirtualSubject(s).ok()) << ValidateVirtualSubject(s).ToString();
  }
}

// The plateau family's stated shapes (DrawPlateauSubject) on 100 seeds,
// inside the ranges.
TEST(PlateauSubject, HasItsShapesInsideTheRanges) {
  const SubjectRanges r;
  for (std::uint64_t seed = 1; seed <= 100; ++seed) {
    const VirtualSubject s = DrawPlateauSubject(seed);
    SCOPED_TRACE(s.name);
    const model::PassiveParams& p = s.truth.passive;
    EXPECT_GE(p.inertia_kgm2, r.min_inertia_kgm2);
    EXPECT_LE(p.inertia_kgm2, r.max_inertia_kgm2);
    EXPECT_GE(s.max_tolerated_ma, r.min_max_tolerated_ma);
    EXPECT_LE(s.max_tolerated_ma, r.max_max_tolerated_ma);
    // Recruitment plateaus at 0.6–0.9 of full activation below the max
    // tolerated amplitude: no more recruited above it.
    const double top = s.truth.irc(s.max_tolerated_ma);
    EXPECT_GE(top, 0.6 - 1e-9);
    EXPECT_LE(top, 0.9 + 1e-9);
    EXPECT_NEAR(s.truth.irc(0.9 * s.max_tolerated_ma), top, 1e-12);
    EXPECT_NEAR(s.truth.irc(100.0), top, 1e-12);
    EXPECT_EQ(s.truth.irc(s.threshold_ma), 0.0);
    EXPECT_GT(s.truth.irc(s.threshold_ma + 1.0), 0.0);
    // Steep end-range stiffness at both ends: over the 5° inside each stop
    // the passive torque changes by ≥ 7 N·m (≥ 20·(1 − e^{−5/8}) N·m of end
    // term, less at most 2 N·m of gravity against it).
    EXPECT_GT(p.torque_angle(110.0) - p.torque_angle(105.0), 7.0);
    EXPECT_LT(p.torque_angle(10.0) - p.torque_angle(15.0), -7.0);
    EXPECT_EQ(p.torque_angle.x().size(), 61u);
    EXPECT_NEAR(p.torque_angle(90.0), 0.0, 1e-9);  // referenced (§6.5)
    // A stable rest angle with ζ in range (Table 6.4).
    const double rest_deg = model::PassiveRestAngle(p);
    EXPECT_GE(rest_deg, 10.0);
    EXPECT_LE(rest_deg, 110.0);
    const model::PassiveLinearisation lin = model::LinearisePassive(p, rest_deg, 0.0);
    EXPECT_GE(lin.damping_ratio, r.min_zeta);
    EXPECT_LE(lin.damping_ratio, r.max_zeta);
    EXPECT_GE(s.truth.contraction.pole_per_s, 20.0);
    EXPECT_LE(s.truth.contraction.pole_per_s, 30.0);
    // Max isometric torque at max tolerated 10–60 N·m.
    double max_torque = 0.0;
    for (double th = 0.0; th <= 120.0; th += 0.5) {
      max_torque = std::max(max_torque,
                            SteadyIsometricActiveTorqueNm(s.truth, s.max_tolerated_ma, th));
    }
    EXPECT_GE(max_torque, 0.99 * r.min_max_torque_nm);
    EXPECT_LE(max_torque, r.max_max_torque_nm + 1e-9);
    EXPECT_NEAR(s.truth.active.torque_angle(90.0), 1.0, 1e-9);  // §6.7
    // Strong potentiation, slow fatigue recovery; the rest as Default().
    EXPECT_GE(s.fidelity.potentiation_max, 0.6);
    EXPECT_LE(s.fidelity.potentiation_max, 1.0);
    EXPECT_GE(s.fidelity.fatigue_recovery_s, 90.0);
    EXPECT_LE(s.fidelity.fatigue_recovery_s, 180.0);
    Fidelity rest = s.fidelity;
    rest.potentiation_max = Fidelity::Default().potentiation_max;
    rest.fatigue_recovery_s = Fidelity::Default().fatigue_recovery_s;
    EXPECT_EQ(rest, Fidelity::Default());
  }
}

TEST(PlateauSubject, SeededAndIndependentOfTheOtherFamilies) {
  EXPECT_EQ(DrawPlateauSubject(42), DrawPlateauSubject(42));
  EXPECT_NE(DrawPlateauSubject(42).truth, DrawPlateauSubject(43).truth);
  EXPECT_NE(DrawPlateauSubject(42).anthropometrics, DrawAnalyticSubject(42).anthropometrics);
  EXPECT_NE(DrawPlateauSubject(42).anthropometrics, DrawVirtualSubject(42).anthropometrics);
  EXPECT_EQ(DrawPlateauSubject(42).name, "plateau-42");
  EXPECT_EQ(DrawSubject(42, SubjectFamily::kPlateau), DrawPlateauSubject(42));
  EXPECT_EQ(SubjectFamilyFromName("plateau"), SubjectFamily::kPlateau);
  EXPECT_EQ(SubjectFamilyName(SubjectFamily::kPlateau), "plateau");
  EXPECT_EQ(SubjectFamilyName(SubjectFamily::kThesis), "thesis");
  // The truth and the fidelity survive the JSON the server sends.
  const VirtualSubject s = DrawPlateauSubject(7);
  const auto back = VirtualSubjectFromJson(nlohmann::json::parse(VirtualSubjectToJson(s).dump()));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(*back, s);
}

TEST(VirtualSubjectJson, RoundTripsThroughText) {
  VirtualSubject s = DrawVirtualSubject(5);
  s.fidelity.cocontraction_per_min = 2.5;
  s.fidelity.quantise_adc = false;
  const std::string text = VirtualSubjectToJson(s).dump();
  const auto back = VirtualSubjectFromJson(nlohmann::json::parse(text));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(*back, s);
}

TEST(VirtualSubjectJson, OptionalSectionsDefault) {
  nlohmann::json j = {{"truth", api::ParameterSetToJson(model::ExampleParameterSet())},
                      {"threshold_ma", 20},
                      {"max_tolerated_ma", 45},
                      {"fidelity", {{"hysteresis_nm", 0.0}}}};
  const auto s = VirtualSubjectFromJson(j);
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  EXPECT_EQ(s->fidelity.hysteresis_nm, 0.0);
  EXPECT_EQ(s->fidelity.series_stiffness_nm_per_deg, Fidelity{}.series_stiffness_nm_per_deg);
  EXPECT_EQ(s->anthropometrics, Anthropometrics{});
}

struct BadCase {
  const char* name;
  std::function<void(nlohmann::json&)> edit;
  const char* field;
};

TEST(VirtualSubjectJson, RejectionsNameTheField) {
  const nlohmann::json good = VirtualSubjectToJson(DrawVirtualSubject(9));
  const std::vector<BadCase> cases = {
      {"missing truth", [](auto& j) { j.erase("truth"); }, "truth"},
      {"bad inertia", [](auto& j) { j["truth"]["passive"]["inertia_kgm2"] = -1; },
       "truth.passive.inertia_kgm2"},
      {"max below threshold", [](auto& j) { j["max_tolerated_ma"] = 1.0; }, "max_tolerated_ma"},
      {"max above bench", [](auto& j) { j["max_tolerated_ma"] = 120.0; }, "max_tolerated_ma"},
      {"negative threshold", [](auto& j) { j["threshold_ma"] = -1.0; }, "threshold_ma"},
      {"threshold not a number", [](auto& j) { j["threshold_ma"] = "x"; }, "threshold_ma"},
      {"typo in fidelity", [](auto& j) { j["fidelity"]["hysterisis_nm"] = 1.0; },
       "fidelity.hysterisis_nm"},
      {"negative magnitude", [](auto& j) { j["fidelity"]["static_friction_nm"] = -0.1; },
       "fidelity.static_friction_nm"},
      {"zero hysteresis angle", [](auto& j) { j["fidelity"]["hysteresis_angle_deg"] = 0.0; },
       "fidelity.hysteresis_angle_deg"},
      {"variation above 1", [](auto& j) { j["fidelity"]["twitch_variation"] = 1.5; },
       "fidelity.twitch_variation"},
      {"quantise not bool", [](auto& j) { j["fidelity"]["quantise_adc"] = 1; },
       "fidelity.quantise_adc"},
      {"zero shank", [](auto& j) { j["anthropometrics"]["shank_length_m"] = 0.0; },
       "anthropometrics.shank_length_m"},
      {"unknown top-level", [](auto& j) { j["colour"] = "red"; }, "colour"},
      {"negative seed", [](auto& j) { j["seed"] = -3; }, "seed"},
  };
  for (const auto& c : cases) {
    nlohmann::json j = good;
    c.edit(j);
    const auto r = VirtualSubjectFromJson(j);
    ASSERT_FALSE(r.ok()) << c.name;
    EXPECT_EQ(r.status().code(), api::ErrorCode::kInvalidArgument) << c.name;
    EXPECT_EQ(r.status().field(), c.field) << c.name << ": " << r.status().ToString();
  }
}

}  // namespace
}  // namespace fesbench::server
