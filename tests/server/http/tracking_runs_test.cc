// Integration: what a run reports about itself, on the real fesbench-server
// with the simulated leg — the bench time it ran (not the plan's, which is
// kept as bench_planned_s), the parameter set a tracking run used, the
// tracking gate refusing only the controllers that invert the set, and a
// holds target lasting the duration asked (docs/API.md, Runs and The bench;
// docs/PROTOCOLS.md, tracking).

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <thread>

#include "server_process.h"

namespace fesbench::testing {
namespace {

using nlohmann::json;

class TrackingRunsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server_ = std::make_unique<ServerProcess>();
    client_ = std::make_unique<httplib::Client>(server_->Client());
    admin_ = server_->admin_token();
    clinician_ = CreateUserToken(*client_, admin_, "clara", "clinician");
    auto truth = Do("GET", "/api/v1/bench/virtual-subject", admin_);
    ASSERT_EQ(truth.status, 200) << truth.text;
    threshold_ma_ = truth.body["threshold_ma"];
    max_tolerated_ma_ = truth.body["max_tolerated_ma"];
    auto subject = Do("POST", "/api/v1/subjects", clinician_,
                      {{"code", "TRACK-01"},
                       {"details",
                        {{"sex", "female"},
                         {"weight_kg", truth.body["anthropometrics"]["body_mass_kg"]},
                         {"shank_length_cm",
                          100.0 * truth.body["anthropometrics"]["shank_length_m"].get<double>()}}},
                       {"legs", {"right"}}});
    ASSERT_EQ(subject.status, 201) << subject.text;
    auto session = Do("POST",
                      "/api/v1/subjects/" + std::to_string(subject.body["id"].get<int>()) +
                          "/sessions",
                      clinician_,
                      {{"leg", "right"},
                       {"date", "2026-11-28"},
                       {"threshold_ma", threshold_ma_},
                       {"max_tolerated_ma", max_tolerated_ma_}});
    ASSERT_EQ(session.status, 201) << session.text;
    runs_ = "/api/v1/sessions/" + std::to_string(session.body["id"].get<int>()) + "/runs";
  }
  void TearDown() override {
    if (server_) {
      EXPECT_EQ(server_->Stderr().find("internal error"), std::string::npos) << server_->Stderr();
    }
  }

  JsonResponse Do(const std::string& method, const std::string& path, const std::string& token,
                  const json& body = nullptr) {
    return Call(*client_, method, path, token, body);
  }

  // Starts a run (expecting 201) and heart-beats it until it ends; its view.
  json RunToEnd(const json& body) {
    auto started = Do("POST", runs_, clinician_, body);
    EXPECT_EQ(started.status, 201) << started.text;
    if (started.status != 201) return json();
    const std::string run = "/api/v1/runs/" + std::to_string(started.body["run_id"].get<int>());
    std::atomic<bool> beating{true};
    std::thread heart([&] {
      auto hb = server_->Client();
      while (beating) {
        Call(hb, "POST", run + "/heartbeat", clinician_);
        std::this_thread::sleep_for(std::chrono::milliseconds(200));
      }
    });
    json view;
    for (int i = 0; i < 1200; ++i) {
      view = Do("GET", run, clinician_).body;
      if (view["state"] != "queued" && view["state"] != "running") break;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    beating = false;
    heart.join();
    return view;
  }

  // The summary of the run's one trial (GET /sessions/{id}/trials).
  json TrialOf(const json& view) {
    EXPECT_EQ(view["trial_ids"].size(), 1u) << view.dump();
    auto trials = Do("GET", runs_.substr(0, runs_.size() - 5) + "/trials", clinician_);
    for (const json& t : trials.body["items"]) {
      if (!view["trial_ids"].empty() && t["id"] == view["trial_ids"][0]) return t;
    }
    return json();
  }

  std::unique_ptr<ServerProcess> server_;
  std::unique_ptr<httplib::Client> client_;
  std::string admin_, clinician_, runs_;
  double threshold_ma_ = 0.0, max_tolerated_ma_ = 0.0;
};

TEST_F(TrackingRunsTest, PidWithItsGainsRunsWithoutASetAndAHoldsTargetLastsTheDurationAsked) {
  // No set for the leg: the model-based controllers and pid without gains
  // are refused (409), pid with its gains runs.
  for (const char* controller : {"inverse_model", "adaptive", "pid"}) {
    auto refused = Do("POST", runs_, clinician_,
                      {{"protocol", "tracking"}, {"parameters", {{"controller", controller}}}});
    EXPECT_EQ(refused.status, 409) << controller << ": " << refused.text;
  }
  const json view = RunToEnd({{"protocol", "tracking"},
                              {"parameters",
                               {{"controller", "pid"},
                                {"target", "holds"},
                                {"duration_s", 30},
                                {"kp_ma_per_deg", 0.05},
                                {"ki_ma_per_deg_s", 0.05}}}});
  ASSERT_EQ(view["state"], "done") << view.dump();
  EXPECT_TRUE(view["used_parameter_set_id"].is_null()) << view.dump();
  EXPECT_EQ(view["parameters"]["parameter_set_id"], 0);
  // The holds last the 30 s asked after the 3 s lead-in, to one sample
  // (they were 29 s: whole hold-and-move cycles).
  const json trial = TrialOf(view);
  ASSERT_TRUE(trial.is_object()) << view.dump();
  EXPECT_EQ(trial["name"], "tracking_holds");
  EXPECT_EQ(trial["num_samples"], (3 + 30) * 200);
  EXPECT_NEAR(trial["duration_s"].get<double>(), 33.0, 0.005 + 1e-9);
  std::cout << "[ figure ] holds for duration_s 30: trial " << trial["duration_s"] << " s ("
            << trial["num_samples"] << " samples) with the 3 s lead-in\n";
}

TEST_F(TrackingRunsTest, RunsReportTheBenchTimeRunAndTheSetUsedAndTheGateSparesPid) {
  // Rapid: its extension search ends when the knee reaches full extension,
  // before its planned end, so it runs less than its plan.
  const json rapid = RunToEnd({{"protocol", "rapid_parameterisation"}});
  ASSERT_EQ(rapid["state"], "done") << rapid.dump();
  const std::int64_t set_id = rapid["parameter_set_id"];
  const double rapid_planned = rapid["bench_planned_s"];
  EXPECT_LT(rapid["bench_total_s"].get<double>(), rapid_planned - 0.1) << rapid.dump();
  EXPECT_DOUBLE_EQ(rapid["bench_total_s"].get<double>(), rapid["bench_elapsed_s"].get<double>());
  auto bench = Do("GET", "/api/v1/bench", clinician_);
  ASSERT_EQ(bench.status, 200) << bench.text;
  const json& progress = bench.body["state"]["progress"];
  EXPECT_DOUBLE_EQ(progress["bench_total_s"].get<double>(), rapid["bench_total_s"].get<double>());
  EXPECT_DOUBLE_EQ(progress["bench_planned_s"].get<double>(), rapid_planned);
  std::cout << "[ figure ] rapid_parameterisation: bench time run " << rapid["bench_total_s"]
            << " s of the plan's " << rapid_planned << " s\n";

  // A tracking run names the set it inverts: "0, the approved set" resolved
  // to the id when it started, in its view and in the stored one.
  const json tracking =
      RunToEnd({{"protocol", "tracking"}, {"parameters", {{"duration_s", 5}}}});
  ASSERT_EQ(tracking["state"], "done") << tracking.dump();
  EXPECT_EQ(tracking["used_parameter_set_id"], set_id) << tracking.dump();
  EXPECT_EQ(tracking["parameters"]["parameter_set_id"], set_id);
  EXPECT_TRUE(tracking["parameter_set_id"].is_null());  // it stored no set
  auto listed = Do("GET", runs_, clinician_);
  ASSERT_EQ(listed.status, 200);
  bool found = false;
  for (const json& r : listed.body["items"]) {
    if (r["run_id"] != tracking["run_id"]) continue;
    found = true;
    EXPECT_EQ(r["used_parameter_set_id"], set_id) << r.dump();
  }
  EXPECT_TRUE(found);

  // A hold at full extension with the maximum 1 mA above threshold: the set
  // says it cannot be held. The gate refuses the controllers that invert
  // the set, not pid, which then runs into the maximum (the interlock holds
  // it there) until the saturation stop ends the run early.
  const double max_ma = threshold_ma_ + 1.0;
  const json weak = {{"target", "holds"}, {"lo_deg", 16},        {"hi_deg", 20},
                     {"duration_s", 20},  {"max_ma", max_ma}};
  for (const char* controller : {"inverse_model", "adaptive"}) {
    json parameters = weak;
    parameters["controller"] = controller;
    auto refused = Do("POST", runs_, clinician_,
                      {{"protocol", "tracking"}, {"parameters", parameters}});
    EXPECT_EQ(refused.status, 409) << controller << ": " << refused.text;
    EXPECT_NE(refused.text.find("cannot be followed"), std::string::npos) << refused.text;
  }
  json parameters = weak;
  parameters["controller"] = "pid";
  const json failed = RunToEnd({{"protocol", "tracking"}, {"parameters", parameters}});
  ASSERT_EQ(failed["state"], "failed") << failed.dump();
  EXPECT_NE(failed["reason"].get<std::string>().find("more than the maximum"), std::string::npos);
  const double planned = failed["bench_planned_s"];
  EXPECT_NEAR(planned, 2.0 + 3.0 + 20.0, 1e-9);  // settle, lead-in, target
  EXPECT_LT(failed["bench_total_s"].get<double>(), planned - 5.0) << failed.dump();
  EXPECT_DOUBLE_EQ(failed["bench_total_s"].get<double>(), failed["bench_elapsed_s"].get<double>());
  EXPECT_LT(failed["progress"].get<double>(), 1.0);
  bench = Do("GET", "/api/v1/bench", clinician_);
  EXPECT_DOUBLE_EQ(bench.body["state"]["progress"]["bench_total_s"].get<double>(),
                   failed["bench_total_s"].get<double>());
  auto trial = Do("GET", "/api/v1/trials/" + std::to_string(failed["trial_ids"][0].get<int>()),
                  clinician_);
  ASSERT_EQ(trial.status, 200) << trial.text;
  for (const json& ch : trial.body["channels"]) {
    if (ch["name"] != "stim_ma") continue;
    const auto values = ch["values"].get<std::vector<double>>();
    ASSERT_FALSE(values.empty());
    EXPECT_LE(*std::max_element(values.begin(), values.end()), max_ma + 1e-9);
  }
  std::cout << "[ figure ] pid on an unreachable hold: failed after " << failed["bench_total_s"]
            << " s of bench time, the plan's " << planned << " s\n";

  // The stored view, after a restart, still names the set.
  const std::int64_t tracking_id = tracking["run_id"];
  ASSERT_EQ(server_->Terminate(), 0);
  const std::unique_ptr<ServerProcess> again = ServerProcess::Restart(*server_);
  client_ = std::make_unique<httplib::Client>(again->Client());
  auto stored = Do("GET", "/api/v1/runs/" + std::to_string(tracking_id), clinician_);
  ASSERT_EQ(stored.status, 200) << stored.text;
  EXPECT_FALSE(stored.body["live"].get<bool>());
  EXPECT_EQ(stored.body["used_parameter_set_id"], set_id) << stored.text;
  EXPECT_EQ(again->Stderr().find("internal error"), std::string::npos) << again->Stderr();
}

}  // namespace
}  // namespace fesbench::testing
