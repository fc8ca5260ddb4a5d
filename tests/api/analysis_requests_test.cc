#include "api/analysis_requests.h"

#include <gtest/gtest.h>

namespace fesbench::api {
namespace {

using nlohmann::json;

TEST(AnalysisRequests, IdentificationRoundTripsThroughItsJson) {
  IdentificationRequest request;
  request.trial_ids = {4, 5, 9};
  request.method = model::IdentificationMethod::kThesis;
  request.passive_method = model::PassiveMethod::kFreeSwing;
  request.contraction_order = 2;
  request.models = {model::ModelKind::kFull, model::ModelKind::kParametric};
  request.breakpoints.active_angle = model::BreakpointSpec{};
  request.breakpoints.active_angle->explicit_x = {20.0, 60.0, 100.0};
  request.breakpoints.passive_velocity = model::BreakpointSpec{};
  request.breakpoints.passive_velocity->count = 5;
  request.inertia_kgm2 = 0.36;
  request.torque_angle_parameter_set_id = 7;

  const Result<IdentificationRequest> back =
      IdentificationRequestFromJson(IdentificationRequestToJson(request));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->trial_ids, request.trial_ids);
  EXPECT_FALSE(back->session_id.has_value());
  EXPECT_EQ(back->passive_method, model::PassiveMethod::kFreeSwing);
  EXPECT_EQ(back->contraction_order, 2);
  EXPECT_EQ(back->models, request.models);
  ASSERT_TRUE(back->breakpoints.active_angle.has_value());
  EXPECT_EQ(back->breakpoints.active_angle->explicit_x, (std::vector<double>{20.0, 60.0, 100.0}));
  ASSERT_TRUE(back->breakpoints.passive_velocity.has_value());
  EXPECT_EQ(back->breakpoints.passive_velocity->count, 5);
  EXPECT_FALSE(back->breakpoints.passive_angle.has_value());
  EXPECT_EQ(back->inertia_kgm2, 0.36);
  EXPECT_EQ(back->torque_angle_parameter_set_id, 7);
}

TEST(AnalysisRequests, AnEmptyIdentificationBodyTakesTheDefaults) {
  const Result<IdentificationRequest> r = IdentificationRequestFromJson(json::object());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->method, model::IdentificationMethod::kThesis);
  EXPECT_EQ(r->irc_method, model::IrcMethod::kRampCorrelation);
  EXPECT_EQ(r->passive_method, model::PassiveMethod::kSimultaneous);
  EXPECT_EQ(r->pole_method, model::PoleMethod::kPeak);
  EXPECT_EQ(r->contraction_order, 3);
  EXPECT_EQ(r->models, std::vector<model::ModelKind>{model::ModelKind::kFull});
}

TEST(AnalysisRequests, IdentificationErrorsNameTheField) {
  const auto field = [](const json& body) {
    return IdentificationRequestFromJson(body).status().field();
  };
  EXPECT_EQ(field({{"session_id", 0}}), "session_id");
  EXPECT_EQ(field({{"session_id", 1.5}}), "session_id");
  EXPECT_EQ(field({{"trial_ids", {1, -2}}}), "trial_ids[1]");
  EXPECT_EQ(field({{"contraction_order", 4}}), "contraction_order");
  EXPECT_EQ(field({{"models", {"full", 3}}}), "models[1]");
  EXPECT_EQ(field({{"breakpoints", {{"active_angle", 1}}}}), "breakpoints.active_angle");
  EXPECT_EQ(field({{"breakpoints", {{"active_angle", {10, "x"}}}}}), "breakpoints.active_angle[1]");
  EXPECT_EQ(field({{"breakpoints", {{"activ_angle", 5}}}}), "breakpoints.activ_angle");
  EXPECT_EQ(field({{"inertia_kgm2", "heavy"}}), "inertia_kgm2");
  EXPECT_EQ(field({{"methd", "rapid"}}), "methd");
  // A name is parsed where it is read: none of a choice's names is refused
  // there, naming the field and the names it takes.
  EXPECT_EQ(field({{"method", "fast"}}), "method");
  EXPECT_EQ(field({{"irc_method", "ramp"}}), "irc_method");
  EXPECT_EQ(field({{"passive_method", "passive_sequential"}}), "passive_method");
  EXPECT_EQ(field({{"pole_method", "Peak"}}), "pole_method");
  EXPECT_EQ(field({{"models", {"full", "hill"}}}), "models[1]");
  EXPECT_EQ(IdentificationRequestFromJson({{"passive_method", "free swing"}}).status().message(),
            "must be sequential, simultaneous or free_swing");
  EXPECT_EQ(IdentificationRequestFromJson(json::array()).status().code(),
            ErrorCode::kInvalidArgument);
}

// Method rapid fits with its own methods: a thesis method named with it is
// refused, never silently ignored (docs/API.md, Jobs).
TEST(AnalysisRequests, RapidRefusesTheThesisMethods) {
  const auto status = [](const json& body) { return IdentificationRequestFromJson(body).status(); };
  EXPECT_EQ(status({{"method", "rapid"}, {"passive_method", "simultaneous"}}).field(),
            "passive_method");
  EXPECT_NE(status({{"method", "rapid"}, {"passive_method", "simultaneous"}}).message().find(
                "needs method thesis"),
            std::string::npos);
  EXPECT_EQ(status({{"method", "rapid"}, {"irc_method", "step"}}).field(), "irc_method");
  EXPECT_EQ(status({{"method", "rapid"}, {"contraction_order", 2}}).field(), "contraction_order");
  EXPECT_EQ(status({{"method", "rapid"}, {"pole_method", "peak"}}).field(), "pole_method");
  // Its own methods, named, are accepted; the thesis method takes them all.
  EXPECT_TRUE(status({{"method", "rapid"},
                      {"passive_method", "free_swing"},
                      {"irc_method", "ramp_deconvolution_ideal"}})
                  .ok());
  EXPECT_TRUE(status({{"method", "thesis"}, {"passive_method", "sequential"}}).ok());
  // What the clients send for rapid reads back.
  IdentificationRequest rapid;
  rapid.session_id = 3;
  rapid.method = model::IdentificationMethod::kRapid;
  const json sent = IdentificationRequestToJson(rapid);
  EXPECT_FALSE(sent.contains("passive_method"));
  EXPECT_TRUE(IdentificationRequestFromJson(sent).ok());
}

// Method passive fits no stimulated trial: the thesis's IRC and contraction
// options are refused by name; it reads back as sent, in free swing.
TEST(AnalysisRequests, PassiveRefusesTheStimulatedOptions) {
  const auto status = [](const json& body) { return IdentificationRequestFromJson(body).status(); };
  EXPECT_EQ(status({{"method", "passive"}, {"irc_method", "step"}}).field(), "irc_method");
  EXPECT_EQ(status({{"method", "passive"}, {"contraction_order", 2}}).field(),
            "contraction_order");
  EXPECT_EQ(status({{"method", "passive"}, {"pole_method", "peak"}}).field(), "pole_method");
  EXPECT_EQ(status({{"method", "passive"}, {"passive_method", "sequential"}}).field(),
            "passive_method");
  const Result<IdentificationRequest> read =
      IdentificationRequestFromJson({{"method", "passive"}, {"trial_ids", {4}}, {"inertia_kgm2", 0.055}});
  ASSERT_TRUE(read.ok()) << read.status().message();
  EXPECT_EQ(read->passive_method, model::PassiveMethod::kFreeSwing);
  const json sent = IdentificationRequestToJson(*read);
  EXPECT_FALSE(sent.contains("irc_method"));
  EXPECT_EQ(sent["inertia_kgm2"], 0.055);
  EXPECT_TRUE(IdentificationRequestFromJson(sent).ok());

  // m·g·l for J from the swings: method passive only, round-tripped.
  const Result<IdentificationRequest> gravity = IdentificationRequestFromJson(
      {{"method", "passive"}, {"trial_ids", {4}}, {"gravity_moment_nm", 1.94}});
  ASSERT_TRUE(gravity.ok()) << gravity.status().message();
  EXPECT_EQ(gravity->gravity_moment_nm, 1.94);
  EXPECT_EQ(IdentificationRequestToJson(*gravity)["gravity_moment_nm"], 1.94);
  EXPECT_EQ(status({{"method", "thesis"}, {"gravity_moment_nm", 1.94}}).field(),
            "gravity_moment_nm");
  EXPECT_EQ(status({{"method", "passive"}, {"gravity_moment_nm", "heavy"}}).field(),
            "gravity_moment_nm");
}

// The names a client offers are the reader's, each once.
TEST(AnalysisRequests, ChoiceNamesAreTheReadersOwn) {
  EXPECT_EQ(PassiveMethodNames(),
            (std::vector<std::string>{"sequential", "simultaneous", "free_swing"}));
  EXPECT_EQ(IdentificationMethodNames(), (std::vector<std::string>{"thesis", "rapid", "passive"}));
  for (const std::string& name : IrcMethodNames()) {
    const Result<IdentificationRequest> r = IdentificationRequestFromJson({{"irc_method", name}});
    ASSERT_TRUE(r.ok()) << name;
    EXPECT_EQ(model::IrcMethodName(r->irc_method), name);
  }
  for (const std::string& name : PoleMethodNames()) {
    EXPECT_TRUE(IdentificationRequestFromJson({{"pole_method", name}}).ok()) << name;
  }
}

TEST(AnalysisRequests, PredictionRoundTripsWithAStimulusOrATrial) {
  PredictionRequest stimulus;
  stimulus.parameter_set_id = 3;
  stimulus.stimulus = StimulusSpec{"prediction_sine", {{"max_ma", 30.0}, {"period_s", 2.5}}};
  stimulus.mode = PredictionMode::kIsometric;
  stimulus.initial_angle_deg = 70.0;
  stimulus.initial_velocity_deg_s = -5.0;
  stimulus.duration_s = 4.0;
  const Result<PredictionRequest> a = PredictionRequestFromJson(PredictionRequestToJson(stimulus));
  ASSERT_TRUE(a.ok()) << a.status().ToString();
  EXPECT_EQ(a->parameter_set_id, 3);
  ASSERT_TRUE(a->stimulus.has_value());
  EXPECT_EQ(a->stimulus->generator, "prediction_sine");
  EXPECT_EQ(a->stimulus->params, stimulus.stimulus->params);
  EXPECT_EQ(a->mode, PredictionMode::kIsometric);
  EXPECT_EQ(a->initial_angle_deg, 70.0);
  EXPECT_EQ(a->initial_velocity_deg_s, -5.0);
  EXPECT_EQ(a->duration_s, 4.0);

  PredictionRequest trial;
  trial.parameter_set_id = 3;
  trial.trial_id = 11;
  trial.fit_scale = true;
  const json j = PredictionRequestToJson(trial);
  EXPECT_FALSE(j.contains("stimulus"));
  EXPECT_FALSE(j.contains("mode"));
  const Result<PredictionRequest> b = PredictionRequestFromJson(j);
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(b->trial_id, 11);
  EXPECT_TRUE(b->fit_scale);
  EXPECT_FALSE(b->mode.has_value());
}

TEST(AnalysisRequests, PredictionErrorsNameTheField) {
  const auto field = [](const json& body) {
    return PredictionRequestFromJson(body).status().field();
  };
  EXPECT_EQ(field(json::object()), "parameter_set_id");
  EXPECT_EQ(field({{"parameter_set_id", 1}, {"mode", "swing"}}), "mode");
  EXPECT_EQ(field({{"parameter_set_id", 1}, {"stimulus", {{"params", json::object()}}}}),
            "stimulus.generator");
  EXPECT_EQ(
      field({{"parameter_set_id", 1},
             {"stimulus", {{"generator", "prediction_step"}, {"params", {{"max_ma", "x"}}}}}}),
      "stimulus.params.max_ma");
  EXPECT_EQ(ParsePredictionMode("free_swing"), PredictionMode::kFreeSwing);
  EXPECT_EQ(PredictionModeName(PredictionMode::kIsometric), "isometric");
  EXPECT_FALSE(ParsePredictionMode("Isometric").has_value());
}

TEST(AnalysisRequests, ComparisonRoundTripsAndNamesItsPairs) {
  ComparisonRequest request;
  request.pairs = {{1, 2, {5, 6}}, {3, 4, {7}}};
  request.metric = "e_abs";
  request.confidence = 0.99;
  const Result<ComparisonRequest> back =
      ComparisonRequestFromJson(ComparisonRequestToJson(request));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ASSERT_EQ(back->pairs.size(), 2u);
  EXPECT_EQ(back->pairs[1].a_parameter_set_id, 3);
  EXPECT_EQ(back->pairs[1].b_parameter_set_id, 4);
  EXPECT_EQ(back->pairs[0].trial_ids, (std::vector<std::int64_t>{5, 6}));
  EXPECT_EQ(back->metric, "e_abs");
  EXPECT_EQ(back->confidence, 0.99);

  EXPECT_EQ(ComparisonRequestFromJson(json::object()).status().field(), "pairs");
  EXPECT_EQ(ComparisonRequestFromJson({{"pairs", {{{"a_parameter_set_id", 1}}}}}).status().field(),
            "pairs[0].b_parameter_set_id");
}

}  // namespace
}  // namespace fesbench::api
