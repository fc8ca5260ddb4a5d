#include "api/analysis_results.h"

#include <gtest/gtest.h>

#include <cmath>

namespace fesbench::api {
namespace {

using nlohmann::json;

// Through text, as a client receives it.
json ThroughText(const json& j) { return json::parse(j.dump()); }

IdentificationResult AnIdentification() {
  IdentificationResult r;
  r.subject_id = 3;
  r.leg_id = 5;
  r.stored = {{11, 2, "full"}, {12, 1, "no_velocity"}};
  r.trial_ids = {7, 8, 9};
  r.report.fit_rms = {{"passive", 0.41}, {"active", 1.25}};
  r.report.values = {{"rank", 9.0}, {"delay_s", 0.025}};
  r.report.warnings = {"active: rank 9 of 10 parameters"};
  r.audit_id = 44;
  return r;
}

PredictionErrors SomeErrors() {
  PredictionErrors e;
  e.channel = "angle_deg";
  e.unit = "deg";
  e.samples = 1200;
  e.e_rms = 2.5;
  e.e_abs = 1.75;
  e.max_abs = 9.0;
  e.normalised_rms = 0.125;
  e.normalised_samples_used = 1100;
  return e;
}

PredictionView APrediction() {
  PredictionView v;
  v.prediction_id = 21;
  v.evaluation_id = 4;
  v.parameter_set_id = 11;
  v.trial_id = 8;
  v.mode = PredictionMode::kIsometric;
  v.model = "full";
  v.initial_angle_deg = 90.0;
  v.initial_velocity_deg_s = -3.5;
  v.samples = 3;
  v.sample_rate_hz = 200.0;
  v.columns = PredictionColumns{{0.0, 0.005, 0.01}, {0.0, 20.0, 20.0}, {90.0, 90.0, 90.0},
                                {0.0, 0.0, 0.0},    {0.0, 1.5, 3.0},   {0.0, 0.1, 0.2}};
  v.errors = SomeErrors();
  v.fitted_scale = 1.125;
  v.share_outside_identified_ranges = 0.25;
  v.released_at_s = 0.5;
  v.strength_at_start = 0.875;
  v.joint_limits = model::JointLimits{12.0, 108.0};
  return v;
}

ComparisonResult AComparison() {
  ComparisonResult r;
  r.metric = "e_rms";
  r.unit = "deg";
  r.pairs = {{1, 2, 3, 5, {{7, 2.0, 3.0}, {8, 2.5, 3.5}}, 2.25, 3.25},
             {4, 6, 9, 10, {{11, 1.0, 1.5}}, 1.0, 1.5}};
  model::PairedTTestResult t;
  t.mean_difference = -0.75;
  t.sd_difference = 0.35;
  t.n = 2;
  t.t = -3.03;
  t.df = 1.0;
  t.p_value = 0.2;
  t.confidence = 0.95;
  t.t_critical = 12.7;
  t.significant = false;
  r.test = t;
  return r;
}

ModelCheck AModelCheck() {
  ModelCheck c;
  c.parameter_set_id = 11;
  c.verdict = ModelVerdict::kUseWithCare;
  c.summary = "Use with care.";
  c.thresholds.angle_good_deg = 2.5;
  ModelCheckTrial swing{.trial_id = 8,
                        .trial_name = "prediction_step",
                        .session_id = 2,
                        .prediction_id = 21,
                        .quantity = "knee angle",
                        .unit = "deg",
                        .e_rms = 4.0,
                        .measured_range = std::nullopt,
                        .share_outside = 0.1,
                        .verdict = ModelVerdict::kUseWithCare,
                        .explanation = "E_RMS 4.0 deg"};
  ModelCheckTrial failed{.trial_id = 9,
                         .trial_name = "prediction_ramp",
                         .session_id = 2,
                         .prediction_id = std::nullopt,
                         .quantity = "torque",
                         .unit = "N.m",
                         .e_rms = std::nullopt,
                         .measured_range = 12.0,
                         .share_outside = std::nullopt,
                         .verdict = ModelVerdict::kDoNotUse,
                         .explanation = "not predictable"};
  c.trials = {swing, failed};
  c.warnings = {"the active curve is extrapolated"};
  c.technical_warnings = {"f_ata: breakpoint 20 deg has support 3"};
  return c;
}

TEST(AnalysisResults, IdentificationReadsBackWhatItWrote) {
  const IdentificationResult r = AnIdentification();
  const Result<IdentificationResult> back =
      IdentificationResultFromJson(ThroughText(IdentificationResultToJson(r)));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(*back, r);
  EXPECT_EQ(IdentificationResultToJson(r)["parameter_sets"][1]["id"], 12);
}

TEST(AnalysisResults, PredictionErrorsReadBackWhatTheyWrote) {
  PredictionErrors e = SomeErrors();
  EXPECT_EQ(*PredictionErrorsFromJson(ThroughText(PredictionErrorsToJson(e))), e);
  e.normalised_rms.reset();
  e.e_ave = -0.5;
  EXPECT_TRUE(PredictionErrorsToJson(e)["normalised_rms"].is_null());
  EXPECT_EQ(*PredictionErrorsFromJson(ThroughText(PredictionErrorsToJson(e))), e);
}

TEST(AnalysisResults, PredictionReadsBackWhatItWrote) {
  const PredictionView v = APrediction();
  EXPECT_EQ(*PredictionViewFromJson(ThroughText(PredictionViewToJson(v))), v);
  // Unstored, without a trial, columns or stops: the nulls read back as unset.
  PredictionView bare;
  bare.parameter_set_id = 2;
  bare.model = "no_velocity";
  const json j = PredictionViewToJson(bare);
  EXPECT_TRUE(j["prediction_id"].is_null());
  EXPECT_TRUE(j["errors"].is_null());
  EXPECT_TRUE(j["joint_limits"].is_null());
  EXPECT_FALSE(j.contains("columns"));
  EXPECT_FALSE(j.contains("sample_rate_hz"));
  EXPECT_EQ(*PredictionViewFromJson(ThroughText(j)), bare);
}

TEST(AnalysisResults, ComparisonReadsBackWhatItWrote) {
  ComparisonResult r = AComparison();
  EXPECT_EQ(*ComparisonResultFromJson(ThroughText(ComparisonResultToJson(r))), r);
  r.test.reset();
  r.test_note = "no paired t-test: it needs at least 2 pairs, got 1";
  const json j = ComparisonResultToJson(r);
  EXPECT_TRUE(j["t_test"].is_null());
  EXPECT_EQ(*ComparisonResultFromJson(ThroughText(j)), r);
}

TEST(AnalysisResults, ModelCheckReadsBackWhatItWrote) {
  const ModelCheck c = AModelCheck();
  const json j = ModelCheckToJson(c);
  EXPECT_EQ(j["verdict"], "use_with_care");
  EXPECT_EQ(j["trials"][1]["verdict"], "do_not_use");
  EXPECT_EQ(*ModelCheckFromJson(ThroughText(j)), c);
}

TEST(AnalysisResults, VerdictNamesReadBack) {
  for (ModelVerdict v : {ModelVerdict::kGoodForControl, ModelVerdict::kUseWithCare,
                         ModelVerdict::kDoNotUse, ModelVerdict::kNoFreshTrials}) {
    EXPECT_EQ(ParseModelVerdict(ModelVerdictName(v)), v);
  }
  EXPECT_FALSE(ParseModelVerdict("fine").has_value());
}

TEST(AnalysisResults, ReadersIgnoreUnknownFields) {
  json j = PredictionViewToJson(APrediction());
  j["from_a_newer_server"] = {1, 2};
  j["errors"]["another_metric"] = 3.0;
  EXPECT_EQ(*PredictionViewFromJson(j), APrediction());
}

TEST(AnalysisResults, UndefinedFiguresReadAsNaN) {
  json j = PredictionErrorsToJson(SomeErrors());
  j["e_rms"] = nullptr;  // how a NaN travels
  const Result<PredictionErrors> e = PredictionErrorsFromJson(j);
  ASSERT_TRUE(e.ok());
  EXPECT_TRUE(std::isnan(e->e_rms));
}

TEST(AnalysisResults, MissingOrMistypedNeededFieldsAreNamed) {
  json prediction = PredictionViewToJson(APrediction());
  prediction.erase("parameter_set_id");
  EXPECT_EQ(PredictionViewFromJson(prediction).status().field(), "parameter_set_id");
  prediction = PredictionViewToJson(APrediction());
  prediction["mode"] = "sideways";
  EXPECT_EQ(PredictionViewFromJson(prediction).status().field(), "mode");
  prediction = PredictionViewToJson(APrediction());
  prediction["errors"]["e_rms"] = "large";
  EXPECT_EQ(PredictionViewFromJson(prediction).status().field(), "errors.e_rms");

  json identification = IdentificationResultToJson(AnIdentification());
  identification["parameter_sets"][1].erase("id");
  EXPECT_EQ(IdentificationResultFromJson(identification).status().field(), "parameter_sets[1].id");
  EXPECT_EQ(IdentificationResultFromJson(json::object()).status().code(),
            ErrorCode::kInvalidArgument);

  json comparison = ComparisonResultToJson(AComparison());
  comparison["pairs"][0]["trials"][1]["trial_id"] = "seven";
  EXPECT_EQ(ComparisonResultFromJson(comparison).status().field(), "pairs[0].trials[1].trial_id");

  json check = ModelCheckToJson(AModelCheck());
  check["trials"][0]["verdict"] = "maybe";
  EXPECT_EQ(ModelCheckFromJson(check).status().field(), "trials[0].verdict");
}

}  // namespace
}  // namespace fesbench::api
