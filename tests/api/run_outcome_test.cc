#include "api/run_outcome.h"

#include <gtest/gtest.h>

#include "api/run.h"

namespace fesbench::api {
namespace {

using nlohmann::json;

RunOutcome EveryFamily() {
  RunOutcome o;
  o.state = RunState::kDone;
  o.parameter_set_id = 7;
  o.used_parameter_set_id = 5;
  o.session_revision = 3;
  ToleranceOutcome t;
  t.test = ToleranceResult{12.5, 30.0, 4.2, 0.1, false, {"a warning"}};
  t.threshold_ma = 12.5;
  t.max_tolerated_ma = 30.0;
  t.subject_signalled_limit = true;
  o.tolerance = t;
  o.amplitude_search = AmplitudeSearchOutcome{22.0, 21.5, false};
  DailyCheckOutcome d;
  d.verdict = model::DailyVerdict::kRefit;
  d.summary = "moved";
  d.drifts.push_back({"irc_threshold_ma", 10.0, 11.0, 1.0, 1.5, false});
  d.refitted = {"irc"};
  d.recruitment_misfit = 0.003;
  d.history_sets = 2;
  d.compared_with = "the set's model";
  d.base_parameter_set_id = 5;
  d.swing_e_rms_stored_deg = 2.0;
  o.daily_check = d;
  o.tracking = TrackingOutcome{{{"tracking_rms_deg", 1.25}, {"charge_uc", 40.0}}};
  return o;
}

TEST(RunOutcomeJson, RoundTripsEveryFamilyWithBooleansAsBooleans) {
  const RunOutcome o = EveryFamily();
  const json j = RunOutcomeToJson(o);
  EXPECT_EQ(j.at("state"), "done");
  EXPECT_TRUE(j.at("tolerance").at("subject_signalled_limit").is_boolean());
  EXPECT_TRUE(j.at("amplitude_search").at("full_extension_reached").is_boolean());
  EXPECT_EQ(j.at("daily_check").at("verdict"), "refit");
  EXPECT_TRUE(j.at("daily_check").at("swing_e_rms_deg").at("updated").is_null());
  auto read = RunOutcomeFromJson(json::parse(j.dump()));
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  EXPECT_EQ(RunOutcomeToJson(*read), j);
  EXPECT_EQ(read->daily_check->verdict, model::DailyVerdict::kRefit);
  EXPECT_EQ(read->tolerance->test->warnings, std::vector<std::string>{"a warning"});
}

TEST(RunOutcomeJson, IgnoresUnknownFieldsAndNamesMissingOrMistypedOnes) {
  json j = RunOutcomeToJson(EveryFamily());
  j["from_a_newer_server"] = 1;
  j["tolerance"]["also_new"] = "x";
  EXPECT_TRUE(RunOutcomeFromJson(j).ok());

  json no_state = j;
  no_state.erase("state");
  EXPECT_EQ(RunOutcomeFromJson(no_state).status().code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(RunOutcomeFromJson(no_state).status().field(), "state");
  json running = j;
  running["state"] = "running";
  EXPECT_EQ(RunOutcomeFromJson(running).status().field(), "state");
  json verdict = j;
  verdict["daily_check"]["verdict"] = "maybe";
  EXPECT_EQ(RunOutcomeFromJson(verdict).status().field(), "daily_check.verdict");
  json flag = j;
  flag["amplitude_search"]["full_extension_reached"] = 1.0;
  EXPECT_EQ(RunOutcomeFromJson(flag).status().field(), "amplitude_search.full_extension_reached");
  json max = j;
  max["tolerance"]["test"].erase("max_tolerated_ma");
  EXPECT_EQ(RunOutcomeFromJson(max).status().field(), "tolerance.test.max_tolerated_ma");
}

TEST(RunOutcomeJson, ResultAndValuesShowTheOutcomeAsTheyAlwaysWere) {
  RunOutcome tolerance;
  tolerance.state = RunState::kDone;
  tolerance.session_revision = 2;
  tolerance.tolerance = ToleranceOutcome{};
  tolerance.tolerance->threshold_ma = 10.0;
  tolerance.tolerance->max_tolerated_ma = 25.0;
  tolerance.tolerance->subject_signalled_limit = true;
  EXPECT_EQ(RunResultJsonOf(tolerance), json({{"threshold_ma", 10.0},
                                              {"max_tolerated_ma", 25.0},
                                              {"session_revision", 2},
                                              {"subject_signalled_limit", true}}));
  EXPECT_EQ(RunValuesOf(tolerance), (std::map<std::string, double>{{"subject_signalled_limit", 1.0}}));

  RunOutcome ceiling = tolerance;
  ceiling.session_revision.reset();
  ceiling.tolerance->max_tolerated_ma.reset();
  ceiling.tolerance->subject_signalled_limit = false;
  ceiling.tolerance->ended_at_ceiling = true;
  ceiling.tolerance->message = "re-test";
  const json r = RunResultJsonOf(ceiling);
  EXPECT_TRUE(r.at("session_revision").is_null());
  EXPECT_TRUE(r.at("max_tolerated_ma").is_null());
  EXPECT_EQ(r.at("ended_at_ceiling"), true);
  EXPECT_EQ(r.at("message"), "re-test");

  RunOutcome daily = EveryFamily();
  daily.tolerance.reset();
  json expected = DailyCheckOutcomeToJson(*daily.daily_check);
  expected["parameter_set_id"] = 7;
  EXPECT_EQ(RunResultJsonOf(daily), expected);

  RunOutcome aborted = EveryFamily();
  aborted.state = RunState::kAborted;
  aborted.parameter_set_id.reset();
  EXPECT_TRUE(RunResultJsonOf(aborted).is_null());

  RunView view;
  ShowOutcome(EveryFamily(), view);
  const json v = RunViewToJson(view);
  EXPECT_EQ(v.at("values").at("full_extension_reached"), 0.0);
  EXPECT_EQ(v.at("values").at("tracking_rms_deg"), 1.25);
  EXPECT_EQ(v.at("tolerance").at("warnings"), json::array({"a warning"}));
  auto back = RunViewFromJson(v);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ASSERT_TRUE(back->outcome.has_value());
  EXPECT_EQ(RunOutcomeToJson(*back->outcome), v.at("outcome"));
  EXPECT_TRUE(back->tolerance.has_value());
}

}  // namespace
}  // namespace fesbench::api
