#include "api/parameter_set_json.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>

namespace fesbench::api {
namespace {

using model::ModelKind;
using model::ParameterSet;
using model::PiecewiseLinear;
using nlohmann::json;
using ::testing::HasSubstr;

// Through text, as a client would send it.
Result<ParameterSet> RoundTrip(const ParameterSet& p) {
  return ParameterSetFromJson(json::parse(ParameterSetToJson(p).dump()));
}

ParameterSet WithProvenance(ParameterSet p) {
  p.provenance.irc_method = "ramp_correlation";
  p.provenance.passive_method = "free_swing";
  p.provenance.active_method = "log_least_squares";
  p.provenance.active_trial_id = 12;
  p.provenance.trial_ids = {10, 11, 12};
  p.provenance.fit_rms = {{"passive_nm", 0.123456789012345678}, {"active_nm", 1.0 / 3.0}};
  p.provenance.warnings = {"low phase-plane coverage"};
  p.provenance.software_version = "0.1.0";
  p.provenance.identified_range_deg = {{"tau_pta", {16.25, 105.5}}, {"f_ata", {12.3, 1.0 / 0.011}}};
  p.provenance.identified_range_deg_s = {{"tau_ptv", {-145.4, 238.2}}, {"f_atv", {-219.6, 151.2}}};
  return p;
}

// The field a JSON document with `mutate` applied to the example is rejected for.
std::string RejectedField(const std::function<void(json&)>& mutate,
                          const ParameterSet& base = model::ExampleParameterSet()) {
  json j = ParameterSetToJson(base);
  mutate(j);
  Result<ParameterSet> r = ParameterSetFromJson(j);
  EXPECT_FALSE(r.ok()) << j.dump();
  if (r.ok()) return "<accepted>";
  EXPECT_EQ(r.status().code(), ErrorCode::kInvalidArgument);
  EXPECT_FALSE(r.status().message().empty());
  return r.status().field();
}

TEST(ParameterSetJson, WritesTheDesignLayout) {
  const json j = ParameterSetToJson(model::ExampleParameterSet());
  EXPECT_EQ(j["model"], "full");
  EXPECT_EQ(j["irc"]["stim_ma"].size(), j["irc"]["activation"].size());
  EXPECT_EQ(j["contraction"]["order"], 3);
  EXPECT_EQ(j["contraction"]["pole_per_s"], 25.0);
  EXPECT_EQ(j["passive"]["inertia_kgm2"], 0.36);
  EXPECT_TRUE(j["passive"]["torque_angle"].contains("angle_deg"));
  EXPECT_TRUE(j["passive"]["torque_angle"].contains("torque_nm"));
  EXPECT_TRUE(j["passive"]["torque_velocity"].contains("velocity_deg_s"));
  EXPECT_EQ(j["active"]["torque_scale_nm"], 40.0);
  EXPECT_TRUE(j["active"]["torque_angle"].contains("gain"));
  EXPECT_TRUE(j["active"]["torque_velocity"].contains("velocity_deg_s"));
  EXPECT_TRUE(j["provenance"].is_object());
  // A full model at default variant values carries no variant sections.
  EXPECT_FALSE(j.contains("single_segment"));
  EXPECT_FALSE(j.contains("parametric"));
}

TEST(ParameterSetJson, ExampleRoundTripsExactly) {
  const ParameterSet p = WithProvenance(model::ExampleParameterSet());
  Result<ParameterSet> back = RoundTrip(p);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(*back, p);  // operator== compares doubles bit for bit
}

TEST(ParameterSetJson, IdentifiedRangesAreLoHiPairsPerCurve) {
  const json j = ParameterSetToJson(WithProvenance(model::ExampleParameterSet()));
  EXPECT_EQ(j["provenance"]["identified_range_deg"]["tau_pta"], json::array({16.25, 105.5}));
  EXPECT_EQ(j["provenance"]["identified_range_deg_s"]["f_atv"], json::array({-219.6, 151.2}));
  // Without ranges: empty objects, and a document without the keys reads.
  const json none = ParameterSetToJson(model::ExampleParameterSet());
  EXPECT_TRUE(none["provenance"]["identified_range_deg"].empty());
  json old = none;
  old["provenance"].erase("identified_range_deg");
  old["provenance"].erase("identified_range_deg_s");
  EXPECT_TRUE(ParameterSetFromJson(old).ok());
  // Bad ranges name the field.
  const auto with = [](json range) {
    return [range](json& d) { d["provenance"]["identified_range_deg"]["tau_pta"] = range; };
  };
  EXPECT_EQ(RejectedField(with(json::array({1.0}))), "provenance.identified_range_deg.tau_pta");
  EXPECT_EQ(RejectedField(with(json::array({20.0, 10.0}))),
            "provenance.identified_range_deg.tau_pta");
  EXPECT_EQ(RejectedField(with(json::array({"a", 10.0}))),
            "provenance.identified_range_deg.tau_pta[0]");
  EXPECT_EQ(RejectedField([](json& d) { d["provenance"]["identified_range_deg_s"] = 3; }),
            "provenance.identified_range_deg_s");
}

TEST(ParameterSetJson, EveryVariantRoundTripsExactly) {
  for (ModelKind kind : model::AllModelKinds()) {
    ParameterSet p = model::ExampleParameterSet();
    p.model = kind;
    p.contraction = {2, 1.0 / 0.037};
    p.single_segment = {-0.0123456789, 2.1 / 3.0, 1e-3 / 7.0, 0.987654321};
    p.parametric = {8.6, 0.45, -3.0 / 7.0, -0.1, 65.25, 35.5, 0.0011, -0.00025};
    Result<ParameterSet> back = RoundTrip(p);
    ASSERT_TRUE(back.ok()) << model::ModelKindName(kind) << ": " << back.status().ToString();
    EXPECT_EQ(*back, p) << model::ModelKindName(kind);
  }
}

TEST(ParameterSetJson, VariantsNeedOnlyTheirOwnParts) {
  // single_segment: no active curves, its own section instead.
  json j = ParameterSetToJson(model::ExampleParameterSet());
  j["model"] = "single_segment";
  j["active"].erase("torque_angle");
  j["active"].erase("torque_velocity");
  j["single_segment"] = {{"a", -0.01}, {"b", 1.9}, {"c", 0.001}, {"d", 1.0}};
  Result<ParameterSet> r = ParameterSetFromJson(j);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->model, ModelKind::kSingleSegment);
  EXPECT_TRUE(r->active.torque_angle.empty());
  EXPECT_EQ(r->single_segment.b, 1.9);
  // Writing it back omits the absent curves and reads back equal.
  Result<ParameterSet> again = RoundTrip(*r);
  ASSERT_TRUE(again.ok()) << again.status().ToString();
  EXPECT_EQ(*again, *r);

  // parametric: Eq. 7.3 replaces the PWL τ_pta.
  j = ParameterSetToJson(model::ExampleParameterSet());
  j["model"] = "parametric";
  j["passive"].erase("torque_angle");
  j["active"].erase("torque_angle");
  j["active"].erase("torque_velocity");
  j["parametric"] = {{"mgl_nm", 8.6},
                     {"k1_nm", 0.5},
                     {"k2_per_rad", -2.0},
                     {"offset_nm", 0.0},
                     {"ata_peak_deg", 65.0},
                     {"ata_width_deg", 35.0},
                     {"atv_slope_neg_per_deg_s", 0.0014},
                     {"atv_slope_pos_per_deg_s", 0.0007}};
  r = ParameterSetFromJson(j);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->parametric.ata_width_deg, 35.0);

  // Provenance is optional; top-level metadata is ignored.
  j = ParameterSetToJson(model::ExampleParameterSet());
  j.erase("provenance");
  j["id"] = 17;
  r = ParameterSetFromJson(j);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->provenance, model::Provenance{});
}

TEST(ParameterSetJson, RejectsNonObject) {
  EXPECT_EQ(RejectedField([](json& j) { j = json::array(); }), "");
}

TEST(ParameterSetJson, RejectsMissingOrUnknownModel) {
  EXPECT_EQ(RejectedField([](json& j) { j.erase("model"); }), "model");
  EXPECT_EQ(RejectedField([](json& j) { j["model"] = 3; }), "model");
  json j = ParameterSetToJson(model::ExampleParameterSet());
  j["model"] = "hill";
  Result<ParameterSet> r = ParameterSetFromJson(j);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().field(), "model");
  EXPECT_THAT(r.status().message(), HasSubstr("unknown model 'hill'"));
  EXPECT_THAT(r.status().message(), HasSubstr("single_segment"));
}

TEST(ParameterSetJson, RejectsMissingRequiredSections) {
  EXPECT_EQ(RejectedField([](json& j) { j.erase("irc"); }), "irc");
  EXPECT_EQ(RejectedField([](json& j) { j.erase("contraction"); }), "contraction");
  EXPECT_EQ(RejectedField([](json& j) { j.erase("passive"); }), "passive");
  EXPECT_EQ(RejectedField([](json& j) { j.erase("active"); }), "active");
  EXPECT_EQ(RejectedField([](json& j) { j["contraction"].erase("pole_per_s"); }),
            "contraction.pole_per_s");
  EXPECT_EQ(RejectedField([](json& j) { j["passive"].erase("inertia_kgm2"); }),
            "passive.inertia_kgm2");
  EXPECT_EQ(RejectedField([](json& j) { j["passive"]["torque_velocity"].erase("torque_nm"); }),
            "passive.torque_velocity.torque_nm");
  EXPECT_EQ(RejectedField([](json& j) { j["active"].erase("torque_scale_nm"); }),
            "active.torque_scale_nm");
  EXPECT_EQ(RejectedField([](json& j) { j["active"]["torque_angle"] = nullptr; }),
            "active.torque_angle");
}

TEST(ParameterSetJson, RejectsMissingVariantSection) {
  EXPECT_EQ(RejectedField([](json& j) { j["model"] = "single_segment"; }), "single_segment");
  EXPECT_EQ(RejectedField([](json& j) { j["model"] = "parametric"; }), "parametric");
  EXPECT_EQ(RejectedField([](json& j) {
              j["model"] = "single_segment";
              j["single_segment"] = {{"a", 0.0}, {"b", 1.0}, {"c", 0.0}};
            }),
            "single_segment.d");
  // The full model still needs its active curves.
  EXPECT_EQ(RejectedField([](json& j) { j["active"].erase("torque_velocity"); }),
            "active.torque_velocity");
}

TEST(ParameterSetJson, RejectsWrongTypes) {
  EXPECT_EQ(RejectedField([](json& j) { j["irc"] = "linear"; }), "irc");
  EXPECT_EQ(RejectedField([](json& j) { j["irc"]["stim_ma"] = 20.0; }), "irc.stim_ma");
  EXPECT_EQ(RejectedField([](json& j) { j["irc"]["activation"][2] = "0.1"; }), "irc.activation[2]");
  EXPECT_EQ(RejectedField([](json& j) { j["contraction"]["pole_per_s"] = "25"; }),
            "contraction.pole_per_s");
  EXPECT_EQ(RejectedField([](json& j) { j["contraction"]["order"] = 3.0; }), "contraction.order");
  EXPECT_EQ(RejectedField([](json& j) { j["passive"]["inertia_kgm2"] = true; }),
            "passive.inertia_kgm2");
  EXPECT_EQ(RejectedField([](json& j) { j["passive"]["torque_angle"]["angle_deg"][0] = nullptr; }),
            "passive.torque_angle.angle_deg[0]");
  EXPECT_EQ(RejectedField([](json& j) { j["single_segment"] = {{"a", "x"}}; }), "single_segment.a");
  EXPECT_EQ(RejectedField([](json& j) {
              j["provenance"]["trial_ids"] = {1, 2.5};
            }),
            "provenance.trial_ids[1]");
  EXPECT_EQ(RejectedField([](json& j) { j["provenance"]["irc_method"] = 7; }),
            "provenance.irc_method");
  EXPECT_EQ(RejectedField([](json& j) { j["provenance"]["fit_rms"]["active_nm"] = "big"; }),
            "provenance.fit_rms.active_nm");
  EXPECT_EQ(RejectedField([](json& j) { j["provenance"]["active_trial_id"] = "12"; }),
            "provenance.active_trial_id");
}

TEST(ParameterSetJson, RejectsUnknownFieldsInsideSections) {
  EXPECT_EQ(RejectedField([](json& j) { j["contraction"]["pole_hz"] = 4.0; }),
            "contraction.pole_hz");
  EXPECT_EQ(RejectedField([](json& j) { j["passive"]["torque_angle"]["angle_rad"] = {1.0}; }),
            "passive.torque_angle.angle_rad");
}

TEST(ParameterSetJson, RejectsNanAndInfinity) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(RejectedField([&](json& j) { j["contraction"]["pole_per_s"] = nan; }),
            "contraction.pole_per_s");
  EXPECT_EQ(RejectedField([&](json& j) { j["passive"]["torque_velocity"]["torque_nm"][4] = inf; }),
            "passive.torque_velocity.torque_nm[4]");
  EXPECT_EQ(RejectedField([&](json& j) { j["active"]["torque_scale_nm"] = -inf; }),
            "active.torque_scale_nm");
  EXPECT_EQ(RejectedField([&](json& j) { j["irc"]["stim_ma"][1] = nan; }), "irc.stim_ma[1]");
  EXPECT_EQ(RejectedField([&](json& j) {
              j["single_segment"] = {{"a", 0.0}, {"b", nan}};
            }),
            "single_segment.b");
  EXPECT_EQ(RejectedField([&](json& j) { j["provenance"]["fit_rms"]["x"] = nan; }),
            "provenance.fit_rms.x");
  // As text, NaN is not JSON at all: the parser refuses it before we see it.
  EXPECT_FALSE(json::accept(R"({"model": "full", "contraction": {"pole_per_s": NaN}})"));
}

TEST(ParameterSetJson, RejectsBreakpointsNotStrictlyIncreasing) {
  EXPECT_EQ(RejectedField([](json& j) { j["irc"]["stim_ma"][3] = j["irc"]["stim_ma"][2]; }),
            "irc.stim_ma[3]");
  EXPECT_EQ(RejectedField([](json& j) { j["passive"]["torque_angle"]["angle_deg"][1] = 5.0; }),
            "passive.torque_angle.angle_deg[1]");
  EXPECT_EQ(
      RejectedField([](json& j) { j["active"]["torque_velocity"]["velocity_deg_s"][8] = 0.0; }),
      "active.torque_velocity.velocity_deg_s[8]");
}

TEST(ParameterSetJson, RejectsEmptyAndMismatchedArrays) {
  EXPECT_EQ(RejectedField([](json& j) {
              j["irc"]["stim_ma"] = json::array();
              j["irc"]["activation"] = json::array();
            }),
            "irc.stim_ma");
  EXPECT_EQ(RejectedField([](json& j) { j["irc"]["activation"].erase(0); }), "irc.activation");
  EXPECT_EQ(RejectedField([](json& j) { j["active"]["torque_angle"]["gain"].push_back(1.0); }),
            "active.torque_angle.gain");
}

TEST(ParameterSetJson, RejectsNonPositiveInertiaAndPole) {
  EXPECT_EQ(RejectedField([](json& j) { j["passive"]["inertia_kgm2"] = -0.36; }),
            "passive.inertia_kgm2");
  EXPECT_EQ(RejectedField([](json& j) { j["passive"]["inertia_kgm2"] = 0.0; }),
            "passive.inertia_kgm2");
  EXPECT_EQ(RejectedField([](json& j) { j["contraction"]["pole_per_s"] = 0.0; }),
            "contraction.pole_per_s");
  EXPECT_EQ(RejectedField([](json& j) { j["contraction"]["pole_per_s"] = -25.0; }),
            "contraction.pole_per_s");
}

TEST(ParameterSetJson, RejectsOrderOtherThanTwoOrThree) {
  EXPECT_EQ(RejectedField([](json& j) { j["contraction"]["order"] = 1; }), "contraction.order");
  EXPECT_EQ(RejectedField([](json& j) { j["contraction"]["order"] = 4; }), "contraction.order");
  EXPECT_EQ(RejectedField([](json& j) { j["contraction"].erase("order"); }), "contraction.order");
}

TEST(ParameterSetJson, RejectsNegativeGainsAndTorqueScale) {
  EXPECT_EQ(RejectedField([](json& j) { j["active"]["torque_scale_nm"] = -1.0; }),
            "active.torque_scale_nm");
  EXPECT_EQ(RejectedField([](json& j) { j["active"]["torque_angle"]["gain"][0] = -0.01; }),
            "active.torque_angle.gain[0]");
  EXPECT_EQ(RejectedField([](json& j) { j["active"]["torque_velocity"]["gain"][3] = -1.0; }),
            "active.torque_velocity.gain[3]");
  // Passive torques may be negative.
  json j = ParameterSetToJson(model::ExampleParameterSet());
  j["passive"]["torque_velocity"]["torque_nm"][0] = -5.0;
  EXPECT_TRUE(ParameterSetFromJson(j).ok());
}

TEST(ParameterSetJson, RejectsIrcOutsideUnitInterval) {
  EXPECT_EQ(RejectedField([](json& j) { j["irc"]["activation"][6] = 1.0001; }),
            "irc.activation[6]");
  EXPECT_EQ(RejectedField([](json& j) { j["irc"]["activation"][0] = -0.001; }),
            "irc.activation[0]");
  json j = ParameterSetToJson(model::ExampleParameterSet());
  j["irc"]["activation"][6] = 1.0;
  j["irc"]["activation"][0] = 0.0;
  EXPECT_TRUE(ParameterSetFromJson(j).ok());
}

TEST(ParameterSetJson, RejectsNonPositiveGaussianWidth) {
  ParameterSet p = model::ExampleParameterSet();
  p.model = ModelKind::kParametric;
  EXPECT_EQ(RejectedField([](json& j) { j["parametric"]["ata_width_deg"] = 0.0; }, p),
            "parametric.ata_width_deg");
}

}  // namespace
}  // namespace fesbench::api
