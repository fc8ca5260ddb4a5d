#include "server/bench/virtual_subject.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "api/parameter_set_json.h"
#include "model/evaluation.h"
#include "model/units.h"
#include "server/bench/virtual_subject_json.h"

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
