#include "api/resources.h"

#include <gtest/gtest.h>

#include "api/parameter_set_json.h"

namespace fesbench::api {
namespace {

using nlohmann::json;

// The shapes as docs/API.md gives them (the server writes them in
// server/http/resources_json.cc; tests/server checks the two agree).

TEST(Resources, ReadsASubject) {
  const json j = {{"id", 4},
                  {"code", "V1-1"},
                  {"created_at_utc", "2026-11-21T10:36:43.123456Z"},
                  {"revision", 2},
                  {"details", {{"sex", "unknown"}}},
                  {"legs", {{{"id", 7}, {"side", "right"}}}}};
  const Result<SubjectResource> s = SubjectResourceFromJson(j);
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  EXPECT_EQ(*s, (SubjectResource{4, "V1-1", 2, {{7, "right"}}}));
}

TEST(Resources, ReadsASession) {
  const json j = {{"id", 9},
                  {"subject_id", 4},
                  {"leg_id", 7},
                  {"leg", "right"},
                  {"date", "2026-11-21"},
                  {"revision", 1},
                  {"details", json::object()}};
  EXPECT_EQ(*SessionResourceFromJson(j), (SessionResource{9, 4, 7, "right", "2026-11-21", 1}));
  json no_leg = j;
  no_leg.erase("leg_id");
  EXPECT_EQ(SessionResourceFromJson(no_leg).status().field(), "leg_id");
}

TEST(Resources, ReadsATrialAndItsKind) {
  json j = {{"id", 12},
            {"session_id", 9},
            {"run_id", 3},
            {"name", "free_swing_passive"},
            {"kind", "free_swing_passive"},
            {"num_samples", 2000},
            {"sample_rate_hz", 200.0},
            {"duration_s", 10.0}};
  const Result<TrialResource> t = TrialResourceFromJson(j);
  ASSERT_TRUE(t.ok()) << t.status().ToString();
  EXPECT_EQ(t->kind, ParseTrialKind("free_swing_passive"));
  EXPECT_EQ(t->run_id, 3);
  j["kind"] = nullptr;
  j["run_id"] = nullptr;
  EXPECT_FALSE(TrialResourceFromJson(j)->kind.has_value());
  EXPECT_FALSE(TrialResourceFromJson(j)->run_id.has_value());
  j["kind"] = "juggling";
  EXPECT_EQ(TrialResourceFromJson(j).status().field(), "kind");
}

TEST(Resources, ReadsAParameterSetWithItsParameters) {
  model::ParameterSet set = model::ExampleParameterSet();
  set.provenance.trial_ids = {12, 13};
  json j = {{"id", 5},
            {"subject_id", 4},
            {"leg_id", 7},
            {"version", 2},
            {"model", "full"},
            {"trial_ids", {12, 13}},
            {"fit_notes", json::array()},
            {"parameters", ParameterSetToJson(set)}};
  const Result<ParameterSetResource> p = ParameterSetResourceFromJson(j);
  ASSERT_TRUE(p.ok()) << p.status().ToString();
  EXPECT_EQ(p->parameters, set);
  EXPECT_EQ(p->trial_ids, (std::vector<std::int64_t>{12, 13}));
  EXPECT_EQ(p->version, 2);

  j["parameters"]["passive"] = "stiff";
  EXPECT_EQ(ParameterSetResourceFromJson(j).status().field().rfind("parameters.", 0), 0u);
  j.erase("parameters");
  const Result<ParameterSetResource> summary = ParameterSetResourceFromJson(j);
  ASSERT_TRUE(summary.ok());
  EXPECT_FALSE(summary->parameters.has_value());
}

}  // namespace
}  // namespace fesbench::api
