// Integration (docs/API.md, "Corrections"): corrections of subjects and sessions as revisions
// (PATCH, revision history, roles, audit), the tolerance test writing its
// result into the session, and rapid parameterisation with an explicit
// inertia — on the real fesbench-server.

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <thread>

#include "api/audit.h"
#include "api/envelope.h"
#include "api/session.h"
#include "api/subject.h"
#include "api/trial_summary.h"
#include "api/user.h"
#include "server_process.h"

namespace fesbench::testing {
namespace {

using nlohmann::json;

class CorrectionsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = std::make_unique<ServerProcess>();
    client_ = std::make_unique<httplib::Client>(server_->Client());
    admin_ = server_->admin_token();
    clinician_ = CreateUserToken(*client_, admin_, "clara", "clinician");
    analyst_ = CreateUserToken(*client_, admin_, "anton", "analyst");
  }
  void TearDown() override {
    EXPECT_EQ(server_->Stderr().find("internal error"), std::string::npos) << server_->Stderr();
  }

  JsonResponse Do(const std::string& method, const std::string& path, const std::string& token,
                  const json& body = nullptr) {
    return Call(*client_, method, path, token, body);
  }

  // A subject without anthropometrics and a session without limits.
  std::pair<std::int64_t, std::int64_t> NewSubjectAndSession(const std::string& code) {
    auto subject = Do("POST", "/api/v1/subjects", clinician_,
                      {{"code", code}, {"details", {{"sex", "female"}}}, {"legs", {"right"}}});
    EXPECT_EQ(subject.status, 201) << subject.text;
    const std::int64_t subject_id = subject.body["id"];
    auto session = Do("POST", "/api/v1/subjects/" + std::to_string(subject_id) + "/sessions",
                      clinician_, {{"leg", "right"}, {"date", "2026-11-23"}});
    EXPECT_EQ(session.status, 201) << session.text;
    return {subject_id, session.body["id"].get<std::int64_t>()};
  }

  // Expects 400 naming `field`, its message containing each of `words`.
  void Expect400(const JsonResponse& r, const std::string& field,
                 const std::vector<std::string>& words) {
    EXPECT_EQ(r.status, 400) << r.text;
    EXPECT_EQ(r.body["error"]["field"], field) << r.text;
    const std::string message = r.body["error"]["message"];
    for (const std::string& w : words) {
      EXPECT_NE(message.find(w), std::string::npos) << "'" << w << "' not in: " << message;
    }
  }

  std::unique_ptr<ServerProcess> server_;
  std::unique_ptr<httplib::Client> client_;
  std::string admin_, clinician_, analyst_;
};

TEST_F(CorrectionsTest, SubjectPatchIsARevisionWithReasonAuditAndHistory) {
  auto [subject_id, session_id] = NewSubjectAndSession("CORR-01");
  const std::string path = "/api/v1/subjects/" + std::to_string(subject_id);

  // Each invalid field: 400 naming it, with unit and range.
  Expect400(Do("PATCH", path, clinician_, {{"reason", "x"}, {"details", {{"weight_kg", 0}}}}),
            "details.weight_kg", {"kg", "(1, 400]"});
  Expect400(Do("PATCH", path, clinician_, {{"reason", "x"}, {"details", {{"weight_kg", "72"}}}}),
            "details.weight_kg", {"kg"});
  Expect400(
      Do("PATCH", path, clinician_, {{"reason", "x"}, {"details", {{"shank_length_cm", 95}}}}),
      "details.shank_length_cm", {"cm", "(10, 80]"});
  Expect400(Do("PATCH", path, clinician_, {{"reason", "x"}, {"details", {{"height_cm", 12}}}}),
            "details.height_cm", {"cm", "(30, 250]"});
  Expect400(Do("PATCH", path, clinician_,
               {{"reason", "x"}, {"details", {{"calf_circumference_cm", 101}}}}),
            "details.calf_circumference_cm", {"cm", "(10, 100]"});
  Expect400(Do("PATCH", path, clinician_, {{"reason", "x"}, {"details", {{"age_years", 131}}}}),
            "details.age_years", {"years", "[0, 130]"});
  Expect400(Do("PATCH", path, clinician_, {{"reason", "x"}, {"details", {{"sex", "f"}}}}),
            "details.sex", {"female"});
  Expect400(Do("PATCH", path, clinician_, {{"reason", "x"}, {"details", {{"mass", 70}}}}),
            "details.mass", {"unknown"});
  Expect400(Do("PATCH", path, clinician_, {{"details", {{"weight_kg", 70}}}}), "reason",
            {"required"});
  Expect400(Do("PATCH", path, clinician_, {{"reason", "  "}, {"details", {{"weight_kg", 70}}}}),
            "reason", {"not empty"});
  Expect400(Do("PATCH", path, clinician_,
               {{"reason", std::string(501, 'r')}, {"details", {{"weight_kg", 70}}}}),
            "reason", {"500"});
  Expect400(Do("PATCH", path, clinician_, {{"reason", "x"}, {"details", json::object()}}),
            "details", {"at least one"});
  // Nothing invalid was stored.
  EXPECT_EQ(Do("GET", path, analyst_).body["revision"], 1);

  // Roles: an analyst may not correct; a missing subject is 404.
  EXPECT_EQ(Do("PATCH", path, analyst_, {{"reason", "x"}, {"details", {{"weight_kg", 70}}}}).status,
            403);
  EXPECT_EQ(Do("PATCH", "/api/v1/subjects/999", clinician_,
               {{"reason", "x"}, {"details", {{"weight_kg", 70}}}})
                .status,
            404);

  auto corrected = Do("PATCH", path, clinician_,
                      {{"reason", "measured at the second visit"},
                       {"details", {{"weight_kg", 71.5}, {"shank_length_cm", 42.0}}}});
  ASSERT_EQ(corrected.status, 200) << corrected.text;
  EXPECT_EQ(corrected.body["revision"], 2);
  EXPECT_DOUBLE_EQ(corrected.body["details"]["weight_kg"].get<double>(), 71.5);
  EXPECT_DOUBLE_EQ(corrected.body["details"]["shank_length_cm"].get<double>(), 42.0);
  EXPECT_EQ(corrected.body["details"]["sex"], "female") << "fields not given are kept";
  // null clears a field (admin may correct too).
  auto cleared = Do("PATCH", path, admin_,
                    {{"reason", "calf was not measured"},
                     {"details", {{"calf_circumference_cm", nullptr}, {"height_cm", 170}}}});
  ASSERT_EQ(cleared.status, 200) << cleared.text;
  EXPECT_EQ(cleared.body["revision"], 3);
  EXPECT_FALSE(cleared.body["details"].contains("calf_circumference_cm"));
  EXPECT_DOUBLE_EQ(cleared.body["details"]["weight_kg"].get<double>(), 71.5);

  auto revisions = Do("GET", path + "/revisions", analyst_);
  ASSERT_EQ(revisions.status, 200) << revisions.text;
  const json& items = revisions.body["items"];
  ASSERT_EQ(items.size(), 3u);
  EXPECT_EQ(items[0]["revision"], 1);
  EXPECT_TRUE(items[0]["corrects_revision"].is_null());
  EXPECT_FALSE(items[0]["details"].contains("weight_kg"));
  EXPECT_EQ(items[1]["revision"], 2);
  EXPECT_EQ(items[1]["corrects_revision"], 1);
  EXPECT_EQ(items[1]["reason"], "measured at the second visit");
  EXPECT_EQ(items[1]["changed_by"], "clara");
  EXPECT_TRUE(items[1]["changed_at_utc"].is_string());
  EXPECT_EQ(items[2]["corrects_revision"], 2);
  EXPECT_EQ(items[2]["changed_by"], "admin");

  // The audit log has the correction with its reason.
  auto audit = Do("GET", "/api/v1/audit?limit=500", admin_);
  ASSERT_EQ(audit.status, 200);
  int found = 0;
  for (const auto& e : audit.body["items"]) {
    if (e["action"] != "PATCH " + path || e["outcome"] != "200") continue;
    ++found;
    EXPECT_EQ(e["target"], "subjects/" + std::to_string(subject_id));
    const std::string summary = e["request_summary"];
    if (e["actor"] == "clara") {
      EXPECT_NE(summary.find("reason: measured at the second visit"), std::string::npos) << summary;
      EXPECT_NE(summary.find("weight_kg=71.5"), std::string::npos) << summary;
    }
  }
  EXPECT_EQ(found, 2) << "the two corrections";
}

TEST_F(CorrectionsTest, SessionPatchValidatesCurrentsAndKeepsHistory) {
  auto [subject_id, session_id] = NewSubjectAndSession("CORR-02");
  (void)subject_id;
  const std::string path = "/api/v1/sessions/" + std::to_string(session_id);

  Expect400(Do("PATCH", path, clinician_, {{"reason", "x"}, {"details", {{"threshold_ma", -1}}}}),
            "details.threshold_ma", {"mA", "[0, 100]"});
  Expect400(
      Do("PATCH", path, clinician_, {{"reason", "x"}, {"details", {{"max_tolerated_ma", 101}}}}),
      "details.max_tolerated_ma", {"mA", "[0, 100]"});
  Expect400(Do("PATCH", path, clinician_,
               {{"reason", "x"}, {"details", {{"threshold_ma", 30}, {"max_tolerated_ma", 20}}}}),
            "details.max_tolerated_ma", {"below the threshold", "mA"});
  Expect400(Do("PATCH", path, clinician_, {{"reason", "x"}, {"details", {{"date", "23.11.2026"}}}}),
            "details.date", {"YYYY-MM-DD"});
  Expect400(Do("PATCH", path, clinician_, {{"reason", "x"}, {"details", {{"date", nullptr}}}}),
            "details.date", {"cannot be cleared"});
  Expect400(Do("PATCH", path, clinician_,
               {{"reason", "x"}, {"details", {{"notes", std::string(4097, 'n')}}}}),
            "details.notes", {"4096"});
  Expect400(Do("PATCH", path, clinician_, {{"reason", "x"}, {"details", {{"leg", "left"}}}}),
            "details.leg", {"unknown"});
  EXPECT_EQ(Do("PATCH", path, analyst_, {{"reason", "x"}, {"details", {{"notes", "n"}}}}).status,
            403);

  auto corrected = Do("PATCH", path, clinician_,
                      {{"reason", "recorded on paper"},
                       {"details", {{"threshold_ma", 18.5}, {"max_tolerated_ma", 31}}}});
  ASSERT_EQ(corrected.status, 200) << corrected.text;
  EXPECT_EQ(corrected.body["revision"], 2);
  EXPECT_DOUBLE_EQ(corrected.body["details"]["threshold_ma"].get<double>(), 18.5);
  EXPECT_EQ(corrected.body["details"]["date"], "2026-11-23");
  // A threshold above the current max tolerated is refused on the merged values.
  Expect400(Do("PATCH", path, clinician_, {{"reason", "x"}, {"details", {{"threshold_ma", 40}}}}),
            "details.max_tolerated_ma", {"below the threshold"});

  auto revisions = Do("GET", path + "/revisions", analyst_);
  ASSERT_EQ(revisions.status, 200);
  ASSERT_EQ(revisions.body["items"].size(), 2u);
  EXPECT_EQ(revisions.body["items"][1]["reason"], "recorded on paper");
  EXPECT_EQ(revisions.body["items"][1]["changed_by"], "clara");
  EXPECT_EQ(revisions.body["items"][1]["corrects_revision"], 1);
  EXPECT_EQ(Do("GET", "/api/v1/sessions/999/revisions", analyst_).status, 404);
}

// The tolerance test stores threshold and max tolerated in the session as a
// revision; rapid_parameterisation then runs, first refused for want of an
// inertia, then accepted with an explicit inertia_kgm2.
TEST_F(CorrectionsTest, ToleranceTestWritesTheSessionAndRapidTakesAnExplicitInertia) {
  auto [subject_id, session_id] = NewSubjectAndSession("CORR-03");
  (void)subject_id;
  const std::string runs = "/api/v1/sessions/" + std::to_string(session_id) + "/runs";

  // Without limits only tolerance_test may run.
  auto refused = Do("POST", runs, clinician_, {{"protocol", "rapid_parameterisation"}});
  EXPECT_EQ(refused.status, 409) << refused.text;

  auto truth = Do("GET", "/api/v1/bench/virtual-subject", admin_);
  ASSERT_EQ(truth.status, 200);
  const double true_max = truth.body["max_tolerated_ma"];
  // Nobody stops the ramp: it ends where the subject signals the limit
  // (below the 60 mA default ceiling), which is what the session records.
  auto run = Do("POST", runs, clinician_,
                {{"protocol", "tolerance_test"}, {"parameters", {{"rate_ma_per_s", 2.0}}}});
  ASSERT_EQ(run.status, 201) << run.text;
  const std::int64_t run_id = run.body["run_id"];
  std::atomic<bool> beating{true};
  std::thread heart([&] {
    auto hb = server_->Client();
    while (beating) {
      Call(hb, "POST", "/api/v1/runs/" + std::to_string(run_id) + "/heartbeat", clinician_);
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
  });
  json view;
  for (int i = 0; i < 600; ++i) {
    view = Do("GET", "/api/v1/runs/" + std::to_string(run_id), analyst_).body;
    if (view["state"] != "queued" && view["state"] != "running") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  beating = false;
  heart.join();
  ASSERT_EQ(view["state"], "done") << view.dump();
  const json& result = view["result"];
  ASSERT_TRUE(result.is_object()) << view.dump();
  EXPECT_EQ(result["session_revision"], 2);
  const double threshold = result["threshold_ma"];
  EXPECT_EQ(result["subject_signalled_limit"], true);
  EXPECT_GE(result["max_tolerated_ma"].get<double>(), true_max);
  EXPECT_LT(result["max_tolerated_ma"].get<double>(), true_max + 0.25);
  EXPECT_GT(threshold, 0.0);
  EXPECT_LT(threshold, true_max);

  auto session = Do("GET", "/api/v1/sessions/" + std::to_string(session_id), analyst_);
  EXPECT_EQ(session.body["revision"], 2);
  EXPECT_DOUBLE_EQ(session.body["details"]["threshold_ma"].get<double>(), threshold);
  EXPECT_DOUBLE_EQ(session.body["details"]["max_tolerated_ma"].get<double>(),
                   result["max_tolerated_ma"].get<double>());
  auto revisions =
      Do("GET", "/api/v1/sessions/" + std::to_string(session_id) + "/revisions", analyst_);
  ASSERT_EQ(revisions.body["items"].size(), 2u);
  EXPECT_EQ(revisions.body["items"][1]["reason"], "tolerance_test run " + std::to_string(run_id));
  EXPECT_EQ(revisions.body["items"][1]["changed_by"], "clara");
  // The runs list carries the same result and vocabulary.
  auto list = Do("GET", runs, analyst_);
  ASSERT_EQ(list.status, 200);
  ASSERT_EQ(list.body["items"].size(), 1u);
  EXPECT_EQ(list.body["items"][0]["run_id"], run_id);
  EXPECT_EQ(list.body["items"][0]["state"], "done");
  EXPECT_EQ(list.body["items"][0]["result"], result);

  // The protocol catalog resolves the amplitude defaults for this session
  // in mA; without a session such a default is null with its rule.
  const double max_tolerated = result["max_tolerated_ma"];
  auto resolved = Do(
      "GET", "/api/v1/protocols/prediction_random_binary?session_id=" + std::to_string(session_id),
      analyst_);
  ASSERT_EQ(resolved.status, 200) << resolved.text;
  auto bare = Do("GET", "/api/v1/protocols", analyst_);
  ASSERT_EQ(bare.status, 200);
  for (const auto& p : resolved.body["parameters"]) {
    if (p["name"] != "amplitude_ma") continue;
    EXPECT_EQ(p["unit"], "mA");
    // To 0.1 mA (docs/PROTOCOLS.md).
    EXPECT_NEAR(p["default"].get<double>(),
                std::round(10.0 * (threshold + 0.6 * (max_tolerated - threshold))) / 10.0, 1e-9);
  }
  for (const auto& protocol : bare.body["protocols"]) {
    EXPECT_TRUE(protocol["thesis_section"].get<std::string>().starts_with("§")) << protocol;
    for (const auto& p : protocol["parameters"]) {
      EXPECT_FALSE(p["label"].get<std::string>().empty());
      if (p["name"] == "amplitude_ma") {
        EXPECT_TRUE(p["default"].is_null()) << p;
        EXPECT_TRUE(p["default_rule"].is_string()) << p;
      }
    }
  }
  EXPECT_EQ(Do("GET", "/api/v1/protocols?session_id=999", analyst_).status, 404);
  EXPECT_EQ(Do("GET", "/api/v1/protocols?session_id=x", analyst_).status, 400);

  // The trial downloads with a file name.
  const std::int64_t trial_id = view["trial_ids"][0];
  auto csv = client_->Get(("/api/v1/trials/" + std::to_string(trial_id) + "?format=csv").c_str(),
                          {{"Authorization", "Bearer " + analyst_}});
  ASSERT_TRUE(csv);
  EXPECT_EQ(csv->status, 200);
  EXPECT_EQ(csv->get_header_value("Content-Disposition"),
            "attachment; filename=\"trial-" + std::to_string(trial_id) + "-tolerance_test.csv\"");
  EXPECT_EQ(csv->body.rfind("t_s,", 0), 0u) << csv->body.substr(0, 80);
  Expect400(Do("GET", "/api/v1/trials/" + std::to_string(trial_id) + "?format=xml", analyst_),
            "format", {"csv"});
  auto trials = Do("GET", "/api/v1/sessions/" + std::to_string(session_id) + "/trials", analyst_);
  ASSERT_EQ(trials.body["items"].size(), 1u);
  EXPECT_EQ(trials.body["items"][0]["kind"], "tolerance_test");
  EXPECT_GT(trials.body["items"][0]["duration_s"].get<double>(), 0.0);

  // The subject has no weight or shank length: rapid needs an explicit inertia.
  auto no_inertia = Do("POST", runs, clinician_, {{"protocol", "rapid_parameterisation"}});
  Expect400(no_inertia, "parameters.inertia_kgm2", {"weight_kg", "shank_length_cm", "kg·m²"});
  auto with_inertia =
      Do("POST", runs, clinician_,
         {{"protocol", "rapid_parameterisation"}, {"parameters", {{"inertia_kgm2", 0.35}}}});
  ASSERT_EQ(with_inertia.status, 201) << with_inertia.text;
  EXPECT_DOUBLE_EQ(with_inertia.body["parameters"]["inertia_kgm2"].get<double>(), 0.35);
  const std::int64_t rapid_id = with_inertia.body["run_id"];
  EXPECT_EQ(Do("POST", "/api/v1/runs/" + std::to_string(rapid_id) + "/cancel", clinician_).status,
            200);
}

// The server's answers read as the api/ types the clients use, and the api
// writers reproduce them exactly (the server writes through them).
template <typename T>
void ExpectReadsBack(const json& answer, json (*to)(const T&), api::Result<T> (*from)(const json&)) {
  const api::Result<T> read = from(answer);
  ASSERT_TRUE(read.ok()) << read.status().ToString() << " in " << answer.dump();
  EXPECT_EQ(to(*read).dump(), answer.dump());
}

template <typename T>
void ExpectItemsReadBack(const json& page, json (*to)(const T&),
                         api::Result<T> (*from)(const json&)) {
  const api::Result<api::Page> read = api::PageFromJson(page);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ASSERT_FALSE(read->items.empty()) << page.dump();
  for (const json& item : read->items) ExpectReadsBack(item, to, from);
}

TEST_F(CorrectionsTest, AnswersReadAsApiTypes) {
  auto [subject_id, session_id] = NewSubjectAndSession("WIRE-01");
  const std::string subject = "/api/v1/subjects/" + std::to_string(subject_id);
  const std::string session = "/api/v1/sessions/" + std::to_string(session_id);
  ASSERT_EQ(Do("PATCH", subject, clinician_,
               {{"reason", "measured"}, {"details", {{"weight_kg", 71.5}, {"age_years", 40}}}})
                .status,
            200);
  ASSERT_EQ(Do("PATCH", session, clinician_,
               {{"reason", "measured"}, {"details", {{"threshold_ma", 11.5}}}})
                .status,
            200);

  ExpectReadsBack(Do("GET", subject, analyst_).body, &api::SubjectToJson, &api::SubjectFromJson);
  ExpectItemsReadBack(Do("GET", "/api/v1/subjects", analyst_).body, &api::SubjectToJson,
                      &api::SubjectFromJson);
  ExpectItemsReadBack(Do("GET", subject + "/revisions", analyst_).body,
                      &api::SubjectRevisionToJson, &api::SubjectRevisionFromJson);
  ExpectReadsBack(Do("GET", session, analyst_).body, &api::SessionToJson, &api::SessionFromJson);
  ExpectItemsReadBack(Do("GET", subject + "/sessions", analyst_).body, &api::SessionToJson,
                      &api::SessionFromJson);
  ExpectItemsReadBack(Do("GET", session + "/revisions", analyst_).body,
                      &api::SessionRevisionToJson, &api::SessionRevisionFromJson);
  ExpectItemsReadBack(Do("GET", "/api/v1/users", admin_).body, &api::UserToJson,
                      &api::UserFromJson);
  ExpectItemsReadBack(Do("GET", "/api/v1/tokens", admin_).body, &api::TokenInfoToJson,
                      &api::TokenInfoFromJson);
  ExpectItemsReadBack(Do("GET", "/api/v1/audit", admin_).body, &api::AuditEntryToJson,
                      &api::AuditEntryFromJson);
  ExpectReadsBack(Do("GET", "/api/v1/me", clinician_).body, &api::SignedInUserToJson,
                  &api::UserFromJson);

  const auto error = api::ErrorAnswerFromJson(Do("GET", "/api/v1/subjects/999999", analyst_).body);
  ASSERT_TRUE(error.has_value());
  EXPECT_EQ(error->code(), api::ErrorCode::kNotFound);
}

}  // namespace
}  // namespace fesbench::testing
