// Protocol descriptions, parameter validation and plans (docs/PROTOCOLS.md).
#include "server/protocols/protocol.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "api/trial_kind.h"
#include "model/parameter_set.h"
#include "model/stimulus_generators.h"
#include "server/protocols/plan.h"
#include "server/protocols/protocol_registry.h"
#include "server/protocols/rapid_identification.h"
#include "server/protocols/run_transitions.h"

namespace fesbench::server::protocols {
namespace {

SubjectContext Subject() {
  SubjectContext s;
  s.threshold_ma = 22.0;
  s.max_tolerated_ma = 42.0;
  s.min_angle_deg = 25.0;
  s.max_angle_deg = 105.0;
  return s;
}

// Runs of non-zero samples of an envelope: (first index, length).
std::vector<std::pair<std::size_t, std::size_t>> Runs(const std::vector<double>& v) {
  std::vector<std::pair<std::size_t, std::size_t>> out;
  for (std::size_t i = 0; i < v.size();) {
    if (v[i] > 0.0) {
      std::size_t j = i;
      while (j < v.size() && v[j] > 0.0) ++j;
      out.emplace_back(i, j - i);
      i = j;
    } else {
      ++i;
    }
  }
  return out;
}

// The thesis's protocols and the routines built on them; a protocol added
// beyond them has its own test (tests/server/catalog/).
TEST(ProtocolCatalog, HoldsEveryProtocolOfDesignTable) {
  const std::set<std::string> want = {
      "tolerance_test",           "isometric_ramp_irc",    "isometric_step_irc",
      "isometric_impulse_irc",    "isometric_prediction",  "passive_sequential",
      "passive_simultaneous",     "free_swing_passive",    "active_random_binary",
      "prediction_step",          "prediction_ramp",       "prediction_sine",
      "prediction_random_binary", "rapid_parameterisation", "tracking", "daily_check"};
  std::set<std::string> have;
  for (const ProtocolDescription& p : ProtocolCatalog()) have.insert(p.name);
  EXPECT_TRUE(std::includes(have.begin(), have.end(), want.begin(), want.end()));
  EXPECT_EQ(ProtocolCatalog().size(), have.size()) << "two protocols share a name";
  EXPECT_EQ(FindProtocol("nope"), nullptr);
  // The catalogue is the registry's, in its order.
  ASSERT_EQ(RegisteredProtocols().size(), ProtocolCatalog().size());
  for (std::size_t i = 0; i < ProtocolCatalog().size(); ++i) {
    EXPECT_EQ(RegisteredProtocols()[i].description.name, ProtocolCatalog()[i].name);
  }
  EXPECT_EQ(ProtocolCatalog().front().name, "tolerance_test");
  EXPECT_EQ(ProtocolCatalog().back().name, "rapid_parameterisation");
}

// Each protocol declares the trial kinds it records (protocol_registry.h):
// every trial its plan makes is of one of them, and no kind has two
// recording protocols.
TEST(ProtocolCatalog, EveryProtocolRecordsTheTrialKindsItDeclares) {
  SubjectContext subject = Subject();
  subject.parameter_set = model::ExampleParameterSet();
  std::map<api::TrialKind, std::string> recorder;
  for (const RegisteredProtocol& r : RegisteredProtocols()) {
    EXPECT_FALSE(r.records.empty()) << r.description.name;
    for (api::TrialKind kind : r.records) {
      EXPECT_TRUE(recorder.emplace(kind, r.description.name).second)
          << api::TrialKindName(kind) << " has two recording protocols";
      EXPECT_EQ(RecordingProtocol(kind), r.description.name);
    }
    api::Result<Plan> plan = MakePlan(r.description.name, {}, subject);
    ASSERT_TRUE(plan.ok()) << r.description.name << ": " << plan.status().ToString();
    for (const TrialPlan& trial : plan->trials) {
      const std::optional<api::TrialKind> kind = api::TrialKindOf(trial.name);
      ASSERT_TRUE(kind.has_value()) << trial.name;
      EXPECT_NE(std::find(r.records.begin(), r.records.end(), *kind), r.records.end())
          << r.description.name << " records " << trial.name << " of an undeclared kind";
    }
  }
  // Validation kinds come from the prediction protocols.
  for (const api::TrialKindInfo& info : api::TrialKinds()) {
    if (!api::IsValidation(info.kind)) continue;
    const ProtocolDescription* p = FindProtocol(RecordingProtocol(info.kind));
    ASSERT_NE(p, nullptr) << info.name;
    EXPECT_TRUE(p->kind == ProtocolKind::kPrediction || p->kind == ProtocolKind::kIsometric)
        << info.name;
  }
}

// The properties clients read instead of protocol names (api::ProtocolInfo).
TEST(ProtocolCatalog, ClientFacingPropertiesBelongToOneProtocolEach) {
  std::vector<std::string> measures, follows, first;
  for (const ProtocolDescription& p : ProtocolCatalog()) {
    if (p.measures_max_tolerated) measures.push_back(p.name);
    if (p.follows_target) follows.push_back(p.name);
    if (p.offered_first) first.push_back(p.name);
  }
  EXPECT_EQ(measures, std::vector<std::string>{"tolerance_test"});
  EXPECT_EQ(follows, std::vector<std::string>{"tracking"});
  EXPECT_EQ(first, std::vector<std::string>{"rapid_parameterisation"});
  const nlohmann::json tolerance = ProtocolToJson(*FindProtocol("tolerance_test"));
  EXPECT_EQ(tolerance.at("measures_max_tolerated"), true);
  EXPECT_EQ(tolerance.at("follows_target"), false);
  EXPECT_EQ(tolerance.at("offered_first"), false);
}

TEST(ProtocolCatalog, ParametersCarryUnitsAndConsistentLimits) {
  const std::set<std::string> unitless = {"conditioning_fraction",
                                          "impulses",
                                          "ramps",
                                          "levels",
                                          "count",
                                          "positions",
                                          "speeds",
                                          "trajectories",
                                          "seed",
                                          "rb1_seed",
                                          "rb2_seed",
                                          "passive_seed",
                                          "active_seed",
                                          "level_fraction",
                                          "release_margin_fraction",
                                          "extension_target_fraction",
                                          "rb_level_min_fraction",
                                          "rb_min_top_fraction",
                                          "dense",
                                          "controller",
                                          "target",
                                          "forgetting",
                                          "parameter_set_id",
                                          "release_count"};
  for (const ProtocolDescription& p : ProtocolCatalog()) {
    std::set<std::string> names;
    for (const ParameterSpec& s : p.parameters) {
      SCOPED_TRACE(p.name + "." + s.name);
      EXPECT_TRUE(names.insert(s.name).second) << "duplicate";
      const bool has_unit = s.name.ends_with("_ma") || s.name.ends_with("_s") ||
                            s.name.ends_with("_deg") || s.name.ends_with("_deg_s") ||
                            s.name.ends_with("_nm") || s.name.ends_with("_ma_per_s") ||
                            s.name.ends_with("_kgm2") || s.name.ends_with("_hz");
      EXPECT_TRUE(has_unit || unitless.count(s.name)) << "name without unit suffix";
      EXPECT_LE(s.min_value, s.max_value);
      if (s.scaling == Scaling::kNone) {
        EXPECT_GE(s.default_value, s.min_value);
        EXPECT_LE(s.default_value, s.max_value);
      }
      if (s.is_rest) {
        EXPECT_GE(s.min_value, p.min_rest_s);
      }
    }
  }
}

TEST(ProtocolCatalog, JsonListsNameVersionAndParameters) {
  const nlohmann::json j = CatalogToJson();
  ASSERT_EQ(j.at("protocols").size(), ProtocolCatalog().size());
  const nlohmann::json& step = j.at("protocols").at(2);
  EXPECT_EQ(step.at("name"), "isometric_step_irc");
  EXPECT_EQ(step.at("version"), 1);
  EXPECT_EQ(step.at("bench_mode"), "locked");
  EXPECT_DOUBLE_EQ(step.at("min_rest_s").get<double>(), 10.0);
  bool found = false;
  for (const auto& p : step.at("parameters")) {
    if (p.at("name") == "rest_s") {
      found = true;
      EXPECT_EQ(p.at("unit"), "s");
      EXPECT_DOUBLE_EQ(p.at("default").get<double>(), 30.0);
      EXPECT_EQ(p.at("rest"), true);
    }
    if (p.at("name") == "max_ma") {
      EXPECT_EQ(p.at("unit"), "mA");
      EXPECT_EQ(p.at("scales_to"), "max_tolerated");
    }
  }
  EXPECT_TRUE(found);
}

// docs/PROTOCOLS.md, "Parameters": parameters say what they are.
TEST(ProtocolCatalog, EveryParameterHasAClinicianLabelAUnitAndAnHonestDefault) {
  for (const ProtocolDescription& p : ProtocolCatalog()) {
    for (const ParameterSpec& spec : p.parameters) {
      const ParameterPresentation look = PresentationOf(spec.name);
      EXPECT_NE(look.label, spec.name) << p.name << "." << spec.name << " has no label";
      EXPECT_EQ(look.label.find("§"), std::string::npos) << spec.name;
      EXPECT_FALSE(look.unit.empty()) << spec.name;
      if (spec.name.ends_with("_fraction")) {
        EXPECT_EQ(look.unit, "1") << spec.name;
      }
      if (spec.name.ends_with("_ma")) {
        EXPECT_EQ(look.unit, "mA") << spec.name;
      }
    }
  }
  // A name means what its protocol needs: tracking's duration is the target's.
  EXPECT_EQ(PresentationOf("duration_s").label, "Length of each stimulation train");
  EXPECT_EQ(PresentationOf(*FindProtocol("tracking")->FindParameter("duration_s")).label,
            "Length of the target (after the lead-in)");
  const nlohmann::json tracking = ProtocolToJson(*FindProtocol("tracking"));
  for (const auto& param : tracking.at("parameters")) {
    if (param.at("name") == "duration_s") {
      EXPECT_EQ(param.at("label"), "Length of the target (after the lead-in)");
    }
  }
  const nlohmann::json bare = ProtocolToJson(*FindProtocol("prediction_random_binary"));
  EXPECT_EQ(bare.at("thesis_section"), "§5.4.5");
  EXPECT_EQ(bare.at("stimulates"), true);
  for (const auto& param : bare.at("parameters")) {
    if (param.at("name") != "amplitude_ma") continue;
    // No default in mA that is not the subject's: null and the rule.
    EXPECT_TRUE(param.at("default").is_null()) << param.dump();
    EXPECT_EQ(param.at("default_rule"), "60 % of threshold→max");
    EXPECT_EQ(param.at("unit"), "mA");
    EXPECT_EQ(param.at("label"), "Random-binary amplitude");
    EXPECT_EQ(param.at("advanced"), false);
  }
  const SubjectContext s = Subject();
  const nlohmann::json resolved =
      ProtocolToJson(*FindProtocol("prediction_random_binary"), &s, true);
  for (const auto& param : resolved.at("parameters")) {
    if (param.at("name") == "amplitude_ma") {
      EXPECT_DOUBLE_EQ(param.at("default").get<double>(),
                       s.threshold_ma + 0.6 * (s.max_tolerated_ma - s.threshold_ma));
    }
    if (param.at("name") == "seed") {
      EXPECT_DOUBLE_EQ(param.at("default").get<double>(), 3.0);
      EXPECT_TRUE(param.at("default_rule").is_null());
    }
  }
  // Measured limits of any precision resolve to 0.1 mA: 17.19 + 0.6·2.87 =
  // 18.912 → 18.9; never above the max tolerated.
  SubjectContext measured = s;
  measured.threshold_ma = 17.19;
  measured.max_tolerated_ma = 20.06;
  const nlohmann::json rounded =
      ProtocolToJson(*FindProtocol("prediction_random_binary"), &measured, true);
  for (const auto& param : rounded.at("parameters")) {
    if (param.at("name") == "amplitude_ma") {
      EXPECT_DOUBLE_EQ(param.at("default"), 18.9);
    }
  }
  // A session without recorded limits resolves no stimulation default.
  const nlohmann::json unmeasured =
      ProtocolToJson(*FindProtocol("prediction_random_binary"), &s, false);
  for (const auto& param : unmeasured.at("parameters")) {
    if (param.at("name") == "threshold_ma") {
      EXPECT_TRUE(param.at("default").is_null());
    }
  }
  EXPECT_EQ(ProtocolToJson(*FindProtocol("rapid_parameterisation")).at("thesis_section"), "§7.4.1");
  EXPECT_EQ(ProtocolToJson(*FindProtocol("passive_simultaneous")).at("thesis_section"), "§5.4.2");
  EXPECT_EQ(ProtocolToJson(*FindProtocol("passive_sequential")).at("stimulates"), false);
  EXPECT_EQ(ProtocolToJson(*FindProtocol("tolerance_test")).at("thesis_section"), "§5.2.1");
}

TEST(ResolveParameters, ScalesDefaultsToTheSubject) {
  const SubjectContext s = Subject();
  auto v = ResolveParameters(*FindProtocol("active_random_binary"), {}, s);
  ASSERT_TRUE(v.ok()) << v.status().ToString();
  EXPECT_DOUBLE_EQ(v->at("threshold_ma"), 22.0);
  EXPECT_DOUBLE_EQ(v->at("max_ma"), 42.0);
  EXPECT_NEAR(v->at("amplitude_ma"), 22.0 + 0.6 * 20.0, 1e-12);
  EXPECT_DOUBLE_EQ(v->at("rest_s"), 10.0);
  auto sim = ResolveParameters(*FindProtocol("passive_simultaneous"), {}, s);
  ASSERT_TRUE(sim.ok());
  EXPECT_DOUBLE_EQ(sim->at("min_angle_deg"), 25.0);
  EXPECT_DOUBLE_EQ(sim->at("max_angle_deg"), 105.0);
}

// docs/SAFETY.md, "Tolerance test ceiling": the tolerance test's ceiling is the recorded max by
// default (60 mA, stated, without one); above a recorded max only with a reason.
TEST(ResolveParameters, ToleranceCeilingFollowsTheRecordedMax) {
  const ProtocolDescription& d = *FindProtocol("tolerance_test");
  SubjectContext recorded = Subject();
  recorded.max_tolerated_ma = 8.5;
  recorded.threshold_ma = 3.0;
  auto v = ResolveParameters(d, {}, recorded);
  ASSERT_TRUE(v.ok()) << v.status().ToString();
  EXPECT_DOUBLE_EQ(v->at("ceiling_ma"), 8.5);
  auto above = ResolveParameters(d, {{"ceiling_ma", 59.998}}, recorded);
  EXPECT_EQ(above.status().field(), "parameters.ceiling_ma");
  auto start = ResolveParameters(d, {{"start_ma", 8.5}}, recorded);
  EXPECT_EQ(start.status().field(), "parameters.start_ma");
  SubjectContext decided = recorded;
  decided.ceiling_above_max = "re-test after four weeks of training";
  auto explicit_ceiling = ResolveParameters(d, {{"ceiling_ma", 20.0}}, decided);
  ASSERT_TRUE(explicit_ceiling.ok()) << explicit_ceiling.status().ToString();
  EXPECT_DOUBLE_EQ(explicit_ceiling->at("ceiling_ma"), 20.0);
  EXPECT_EQ(ResolveParameters(d, {}, decided).status().field(), "ceiling_reason")
      << "a reason that authorises nothing";
  // Only printable words authorise it: not blank, not control characters.
  for (const std::string& reason :
       {std::string(), std::string(" "), std::string(" \t\r\n "), std::string("\0x", 2),
        std::string("x\x1b[2J"), std::string("x\x7f"), std::string("x\xc2\x9b")}) {
    decided.ceiling_above_max = reason;
    const auto refused = ResolveParameters(d, {{"ceiling_ma", 20.0}}, decided);
    EXPECT_EQ(refused.status().field(), "ceiling_reason") << ::testing::PrintToString(reason);
    EXPECT_NE(refused.status().message().find("printable"), std::string::npos);
  }
  decided.ceiling_above_max = "  re-test: \xc3\xa9l\xc3\xa8ve ";  // spaces around, UTF-8 inside
  EXPECT_TRUE(ResolveParameters(d, {{"ceiling_ma", 20.0}}, decided).ok());
  SubjectContext other = Subject();
  other.ceiling_above_max = "x";
  EXPECT_EQ(ResolveParameters(*FindProtocol("isometric_ramp_irc"), {}, other).status().field(),
            "ceiling_reason");

  SubjectContext first = Subject();  // first session of a new subject
  first.max_tolerated_recorded = false;
  first.threshold_ma = 0.0;
  first.max_tolerated_ma = 100.0;
  auto found = ResolveParameters(d, {}, first);
  ASSERT_TRUE(found.ok());
  EXPECT_DOUBLE_EQ(found->at("ceiling_ma"), 60.0);
  EXPECT_TRUE(ResolveParameters(d, {{"ceiling_ma", 80.0}}, first).ok());
  EXPECT_EQ(ResolveParameters(d, {{"start_ma", 61.0}}, first).status().field(),
            "parameters.start_ma");

  // The catalogue states the rule, and the default for a session.
  const auto ceiling_of = [](const nlohmann::json& j) {
    for (const auto& p : j.at("parameters")) {
      if (p.at("name") == "ceiling_ma") return p;
    }
    return nlohmann::json();
  };
  const nlohmann::json bare = ceiling_of(ProtocolToJson(d));
  EXPECT_TRUE(bare.at("default").is_null());
  EXPECT_EQ(bare.at("default_rule"), "the session's max tolerated amplitude; 60 mA when none is recorded");
  EXPECT_DOUBLE_EQ(ceiling_of(ProtocolToJson(d, &recorded, true)).at("default").get<double>(), 8.5);
  EXPECT_DOUBLE_EQ(ceiling_of(ProtocolToJson(d, &first, false)).at("default").get<double>(), 60.0);
}

TEST(ResolveParameters, RejectsBadValuesNamingTheParameter) {
  const SubjectContext s = Subject();
  const ProtocolDescription& step = *FindProtocol("isometric_step_irc");
  auto unknown = ResolveParameters(step, {{"bogus_s", 1.0}}, s);
  ASSERT_FALSE(unknown.ok());
  EXPECT_EQ(unknown.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(unknown.status().field(), "parameters.bogus_s");

  auto rest = ResolveParameters(step, {{"rest_s", 5.0}}, s);
  ASSERT_FALSE(rest.ok());
  EXPECT_EQ(rest.status().field(), "parameters.rest_s");
  EXPECT_NE(rest.status().message().find("rest below minimum"), std::string::npos);

  auto range = ResolveParameters(step, {{"levels", 1.0}}, s);
  ASSERT_FALSE(range.ok());
  EXPECT_EQ(range.status().field(), "parameters.levels");
  auto whole = ResolveParameters(step, {{"levels", 4.5}}, s);
  ASSERT_FALSE(whole.ok());
  EXPECT_EQ(whole.status().field(), "parameters.levels");
  auto nan = ResolveParameters(step, {{"burst_s", std::nan("")}}, s);
  ASSERT_FALSE(nan.ok());
  EXPECT_EQ(nan.status().field(), "parameters.burst_s");

  auto stim = ResolveParameters(step, {{"max_ma", 50.0}}, s);
  ASSERT_FALSE(stim.ok());
  EXPECT_EQ(stim.status().field(), "parameters.max_ma");
  EXPECT_NE(stim.status().message().find("max tolerated"), std::string::npos);

  auto angle =
      ResolveParameters(*FindProtocol("passive_simultaneous"), {{"min_angle_deg", 15.0}}, s);
  ASSERT_FALSE(angle.ok());
  EXPECT_EQ(angle.status().field(), "parameters.min_angle_deg");

  // Implicit and explicit angles stay inside the range of motion.
  auto lock =
      ResolveParameters(*FindProtocol("isometric_ramp_irc"), {{"lock_angle_deg", 107.0}}, s);
  ASSERT_FALSE(lock.ok());
  EXPECT_EQ(lock.status().field(), "parameters.lock_angle_deg");
  SubjectContext low = s;
  low.max_angle_deg = 80.0;  // the 90° lock of the defaults is outside
  auto iso = ResolveParameters(*FindProtocol("isometric_step_irc"), {}, low);
  ASSERT_FALSE(iso.ok());
  EXPECT_EQ(iso.status().field(), "parameters.lock_angle_deg");
  auto sim90 = MakePlan("passive_simultaneous", {}, low);
  ASSERT_FALSE(sim90.ok());
  EXPECT_NE(sim90.status().message().find("90"), std::string::npos);

  SubjectContext bad = s;
  bad.max_tolerated_ma = 10.0;  // below threshold
  auto subj = ResolveParameters(step, {}, bad);
  ASSERT_FALSE(subj.ok());
  EXPECT_EQ(subj.status().field(), "subject.max_tolerated_ma");
}

TEST(Plan, UnknownProtocolIsNotFound) {
  auto p = MakePlan("no_such", {}, Subject());
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(p.status().code(), api::ErrorCode::kNotFound);
}

TEST(Plan, RampIrcFollowsFigure57) {
  auto plan = MakePlan("isometric_ramp_irc", {}, Subject());
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  ASSERT_EQ(plan->trials.size(), 1u);
  // Lock 1.5 s, 50-sample offset, then the 16 s sequence of Fig. 5-7.
  EXPECT_EQ(plan->total_ticks(), 1500 + 50 + 16000);
  const model::SampledSignal env = TrialEnvelope(*plan, 0);
  ASSERT_EQ(env.size(), 10u + 3200u);
  const auto runs = Runs(env.values);
  ASSERT_EQ(runs.size(), 5u);  // conditioning, 2 impulses, 2 ramps
  EXPECT_EQ(runs[0], (std::pair<std::size_t, std::size_t>{10, 600}));  // 3 s burst
  EXPECT_NEAR(env.values[10], 22.0 + 0.75 * 20.0, 1e-9);               // 75 % of range
  EXPECT_EQ(runs[1].first, 10u + 800u);                                // impulse at 4 s
  EXPECT_EQ(runs[1].second, 1u);
  EXPECT_DOUBLE_EQ(env.values[runs[1].first], 42.0);  // at max
  EXPECT_EQ(runs[2].first, 10u + 1000u);              // impulse at 5 s
  EXPECT_EQ(runs[3].first, 10u + 1200u);              // ramp at 6 s
  const double ramp_max = *std::max_element(env.values.begin() + 1210, env.values.begin() + 2010);
  EXPECT_NEAR(ramp_max, 42.0, 1e-9);
  EXPECT_NEAR(env.values[runs[3].first], 17.0, 0.05);  // threshold − 5 mA
  EXPECT_EQ(runs[4].first, 10u + 2200u);               // second ramp at 11 s (1 s rest)
}

TEST(Plan, StepIrcHasTenBurstsWithThirtySecondRests) {
  auto plan = MakePlan("isometric_step_irc", {}, Subject());
  ASSERT_TRUE(plan.ok());
  const model::SampledSignal env = TrialEnvelope(*plan, 0);
  const auto runs = Runs(env.values);
  ASSERT_EQ(runs.size(), 10u);
  for (std::size_t k = 0; k < runs.size(); ++k) {
    EXPECT_EQ(runs[k].second, 600u);  // 3 s bursts at 200 Hz
    const double level = 22.0 + 20.0 * static_cast<double>(k) / 9.0;
    EXPECT_NEAR(env.values[runs[k].first + 599], level, 1e-9);
    if (k > 0) {
      EXPECT_EQ(runs[k].first - (runs[k - 1].first + 600), 6000u);  // 30 s rest
    }
  }
  double shortest_rest = 1e9;
  int offsets = 0;
  for (const Step& s : plan->steps) {
    if (s.phase == StepPhase::kRest && s.trial == 0 && s.ticks > 1000) {
      shortest_rest = std::min(shortest_rest, s.ticks / 1000.0);
      EXPECT_DOUBLE_EQ(s.min_rest_s, 10.0);
    }
    if (s.phase == StepPhase::kOffset) ++offsets;
  }
  EXPECT_EQ(offsets, 10);                   // one 50-sample offset before every burst (§5.3)
  EXPECT_NEAR(shortest_rest, 29.95, 1e-9);  // 30 s minus the 50 ms offset
}

TEST(Plan, ImpulseIrcIsThirtyPulsesOneSecondApart) {
  auto plan = MakePlan("isometric_impulse_irc", {}, Subject());
  ASSERT_TRUE(plan.ok());
  const model::SampledSignal env = TrialEnvelope(*plan, 0);
  const auto runs = Runs(env.values);
  ASSERT_EQ(runs.size(), 30u);
  EXPECT_NEAR(env.values[runs.front().first], 17.0, 1e-9);
  EXPECT_NEAR(env.values[runs.back().first], 42.0, 1e-9);
  for (std::size_t k = 1; k < runs.size(); ++k) {
    EXPECT_EQ(runs[k].second, 1u);
    EXPECT_EQ(runs[k].first - runs[k - 1].first, 200u);
  }
}

TEST(Plan, PredictionStepRampSineTimings) {
  const SubjectContext s = Subject();
  auto step = MakePlan("prediction_step", {}, s);
  ASSERT_TRUE(step.ok());
  auto env = TrialEnvelope(*step, 0);
  auto runs = Runs(env.values);
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_EQ(runs[0].first, 10u + 100u);  // onset 0.5 s after the offset lead
  EXPECT_EQ(runs[0].second, 600u);       // 3 s
  EXPECT_NEAR(env.values[runs[0].first], 22.0 + 0.75 * 20.0, 1e-9);
  EXPECT_EQ(env.size() - (runs[0].first + runs[0].second), 300u);  // 1.5 s after

  auto ramp = MakePlan("prediction_ramp", {}, s);
  ASSERT_TRUE(ramp.ok());
  env = TrialEnvelope(*ramp, 0);
  EXPECT_EQ(env.size(), 10u + 2000u);
  const auto peak = std::max_element(env.values.begin(), env.values.end());
  EXPECT_NEAR(*peak, 42.0, 0.1);
  EXPECT_NEAR(static_cast<double>(peak - env.values.begin() - 10) / 200.0, 5.0, 0.01);

  auto sine = MakePlan("prediction_sine", {}, s);
  ASSERT_TRUE(sine.ok());
  env = TrialEnvelope(*sine, 0);
  EXPECT_EQ(env.size(), 10u + 1800u);       // 5 + 2 + 1 + 1 s
  EXPECT_NEAR(env.values[10], 27.0, 1e-9);  // threshold + 5 mA
}

TEST(Plan, RapidParameterisationIsUnderThirtySeconds) {
  SubjectContext subject = Subject();
  subject.inertia_kgm2 = 0.3;  // the fit needs one (§7.4.1)
  auto plan = MakePlan("rapid_parameterisation", {}, subject);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  EXPECT_LT(plan->duration_s(), 30.0);  // §7.4.1 (the search may end sooner)
  ASSERT_EQ(plan->trials.size(), 7u);
  const auto* rapid = dynamic_cast<const RapidIdentification*>(plan->analysis.get());
  ASSERT_NE(rapid, nullptr);
  EXPECT_EQ(rapid->phase(), StepPhase::kIdentify);
  EXPECT_EQ(plan->trials[0].mode, MotorMode::kLocked);
  // The held knee before each release (its torque measures J), then the swing.
  for (std::size_t k : {1u, 3u}) EXPECT_EQ(plan->trials[k].mode, MotorMode::kPosition);
  for (std::size_t k : {2u, 4u, 5u, 6u}) EXPECT_EQ(plan->trials[k].mode, MotorMode::kDecoupled);
  EXPECT_EQ(rapid->settings().swing_trials, (std::vector<int>{2, 4, 5}));
  EXPECT_EQ(rapid->settings().release_trials,
            (std::vector<std::pair<int, int>>{{1, 2}, {3, 4}}));
  EXPECT_EQ(rapid->settings().active_trial, 6);
  // Ramp, holds, swings and the active trial: every trial of the plan.
  EXPECT_EQ(FittedTrials(rapid->settings()), (std::vector<int>{0, 1, 2, 3, 4, 5, 6}));
  // The isometric part: 2 impulses and one 4 s ramp.
  const auto runs = Runs(TrialEnvelope(*plan, 0).values);
  ASSERT_EQ(runs.size(), 3u);
  EXPECT_EQ(runs[0].second, 1u);
  EXPECT_EQ(runs[1].second, 1u);
  EXPECT_NEAR(runs[2].second / 200.0, 4.0, 0.01);
  // Releases 5 % of the range inside each end, after a motor move there.
  const double rom = subject.max_angle_deg - subject.min_angle_deg;
  std::vector<double> release_angles;
  for (std::size_t i = 1; i < plan->steps.size(); ++i) {
    const Step& s = plan->steps[i];
    if ((s.trial == 2 || s.trial == 4) && plan->steps[i - 1].trial != s.trial) {
      EXPECT_EQ(s.motor_mode, MotorMode::kDecoupled);
      EXPECT_EQ(plan->steps[i - 1].motor_mode, MotorMode::kPosition);
      EXPECT_EQ(plan->steps[i - 1].trial, s.trial - 1);  // the recorded hold
      release_angles.push_back(plan->steps[i - 1].setpoint_deg);
    }
  }
  EXPECT_EQ(release_angles, (std::vector<double>{subject.max_angle_deg - 0.05 * rom,
                                                 subject.min_angle_deg + 0.05 * rom}));
  EXPECT_EQ(TrialEnvelope(*plan, 2).size(), 360u);  // 1.8 s swings
  EXPECT_EQ(TrialEnvelope(*plan, 4).size(), 360u);
  // The extension search: threshold → max in 3 s, ending at 10 % of the range
  // inside full extension; then 0.6 s of fall.
  const model::SampledSignal search = TrialEnvelope(*plan, 5);
  ASSERT_EQ(search.size(), 600u + 120u);
  EXPECT_NEAR(search.values[0], subject.threshold_ma, 0.1);
  EXPECT_NEAR(search.values[599], subject.max_tolerated_ma, 1e-9);
  EXPECT_EQ(search.values[600], 0.0);
  bool has_end = false;
  for (const Step& s : plan->steps) {
    if (s.end_below_angle_deg) {
      has_end = true;
      EXPECT_DOUBLE_EQ(*s.end_below_angle_deg, subject.min_angle_deg + 0.1 * rom);
    }
  }
  EXPECT_TRUE(has_end);
  // The dense train: 10 s, every ON level between threshold + 50 % of
  // threshold→amplitude and the amplitude (60 % of threshold→max as planned).
  const model::SampledSignal rb = TrialEnvelope(*plan, 6);
  EXPECT_EQ(rb.size(), 10u + 2000u);
  const double amp = subject.threshold_ma + 0.6 * (subject.max_tolerated_ma - subject.threshold_ma);
  std::set<double> levels;
  for (double u : rb.values) {
    if (u == 0.0) continue;
    EXPECT_GE(u, subject.threshold_ma + 0.5 * (amp - subject.threshold_ma) - 1e-9);
    EXPECT_LE(u, amp + 1e-9);
    levels.insert(u);
  }
  EXPECT_GT(levels.size(), 3u);
  ASSERT_TRUE(plan->adaptive_amplitude.has_value());
  EXPECT_EQ(plan->adaptive_amplitude->target_torque_nm, 0.0);
  EXPECT_EQ(plan->adaptive_amplitude->trials, std::vector<int>{6});
}

TEST(Plan, MotorProtocolsCoverTheRangeAndSequentialTimings) {
  const SubjectContext s = Subject();
  auto sim = MakePlan("passive_simultaneous", {}, s);
  ASSERT_TRUE(sim.ok());
  ASSERT_EQ(sim->trials.size(), 2u);
  double lo = 1e9, hi = -1e9;
  int moves = 0;
  for (const Step& st : sim->steps) {
    if (!st.trajectory) continue;
    ++moves;
    EXPECT_EQ(st.ticks, 10000);  // 10 s trajectories
    for (int k = 0; k <= 10000; k += 5) {
      const double a = st.trajectory->At(k / 1000.0).angle_deg;
      lo = std::min(lo, a);
      hi = std::max(hi, a);
    }
  }
  EXPECT_EQ(moves, 2);
  EXPECT_GE(lo, 25.0 - 1e-9);
  EXPECT_LE(hi, 105.0 + 1e-9);
  EXPECT_GT(hi - lo, 0.9 * 80.0);  // scaled to the subject's range

  auto seq = MakePlan("passive_sequential", {}, s);
  ASSERT_TRUE(seq.ok());
  ASSERT_EQ(seq->trials.size(), 2u);
  std::vector<std::int64_t> move_ticks;
  for (const Step& st : seq->steps) {
    if (st.trajectory) move_ticks.push_back(st.ticks);
  }
  ASSERT_EQ(move_ticks.size(), 2u);
  EXPECT_EQ(move_ticks[0], 451000);  // 10 + 40·(1 + 10) + 1 s (§5.4.1)
  EXPECT_EQ(move_ticks[1], 200000);  // 8 speeds × 2 × (10 s + 2.5 s)
}

TEST(RunState, TransitionTable) {
  EXPECT_EQ(NextState(RunState::kQueued, RunTransition::kStart), RunState::kRunning);
  EXPECT_EQ(NextState(RunState::kRunning, RunTransition::kComplete), RunState::kDone);
  EXPECT_EQ(NextState(RunState::kRunning, RunTransition::kEStop), RunState::kAborted);
  EXPECT_EQ(NextState(RunState::kRunning, RunTransition::kWatchdog), RunState::kAborted);
  EXPECT_EQ(NextState(RunState::kRunning, RunTransition::kError), RunState::kFailed);
  EXPECT_EQ(NextState(RunState::kQueued, RunTransition::kComplete), std::nullopt);
  for (RunState final : {RunState::kDone, RunState::kFailed, RunState::kAborted}) {
    EXPECT_TRUE(IsFinal(final));
    for (RunTransition t :
         {RunTransition::kStart, RunTransition::kComplete, RunTransition::kCancel,
          RunTransition::kEStop, RunTransition::kWatchdog, RunTransition::kError}) {
      EXPECT_EQ(NextState(final, t), std::nullopt);
    }
  }
  EXPECT_EQ(RunStateName(RunState::kAborted), "aborted");
}

TEST(ResolveChoiceNames, TurnsChoiceNamesIntoIndicesAndNamesWhatItRefuses) {
  api::StartRunRequest request;
  request.protocol = "tracking";
  request.parameters["duration_s"] = 20.0;
  request.choices["target"] = "uploaded";
  request.choices["controller"] = "pid";
  const api::Result<api::StartRunRequest> resolved = ResolveChoiceNames(request);
  ASSERT_TRUE(resolved.ok()) << resolved.status().ToString();
  EXPECT_TRUE(resolved->choices.empty());
  EXPECT_EQ(resolved->parameters,
            (ParameterValues{{"duration_s", 20.0}, {"target", 3.0}, {"controller", 0.0}}));

  api::StartRunRequest unknown = request;
  unknown.protocol = "juggling";
  const api::Result<api::StartRunRequest> not_found = ResolveChoiceNames(unknown);
  ASSERT_FALSE(not_found.ok());
  EXPECT_EQ(not_found.status().code(), api::ErrorCode::kNotFound);
  EXPECT_EQ(not_found.status().message(), "protocol juggling not found");
  EXPECT_EQ(not_found.status().field(), "protocol");

  api::StartRunRequest other = request;
  other.choices["target"] = "circle";
  const api::Result<api::StartRunRequest> not_a_choice = ResolveChoiceNames(other);
  ASSERT_FALSE(not_a_choice.ok());
  EXPECT_EQ(not_a_choice.status().message(), "'circle' is not one of sine, holds, ramp, uploaded");
  EXPECT_EQ(not_a_choice.status().field(), "parameters.target");

  api::StartRunRequest number = request;
  number.choices = {{"duration_s", "long"}};
  const api::Result<api::StartRunRequest> not_choice_parameter = ResolveChoiceNames(number);
  ASSERT_FALSE(not_choice_parameter.ok());
  EXPECT_EQ(not_choice_parameter.status().message(), "must be a number, got string");
  EXPECT_EQ(not_choice_parameter.status().field(), "parameters.duration_s");
}

}  // namespace
}  // namespace fesbench::server::protocols
