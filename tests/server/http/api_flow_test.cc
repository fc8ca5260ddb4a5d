// Integration: the real fesbench-server over HTTP, end to end:
// subject and session, virtual subject, rapid_parameterisation with its
// event stream followed to the end, the stored parameter set against the
// virtual subject's truth, a prediction job, the history; then SIGTERM
// during a run ends it safely with exit code 0.

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <atomic>
#include <cmath>
#include <thread>

#include "server_process.h"

namespace fesbench::testing {
namespace {

using nlohmann::json;

// Reads a whole SSE stream; returns the events as (event name, data JSON).
std::vector<std::pair<std::string, json>> FollowStream(int port, const std::string& path,
                                                       const std::string& token) {
  httplib::Client client("127.0.0.1", port);
  client.set_read_timeout(30);
  std::string buffer;
  std::vector<std::pair<std::string, json>> events;
  auto result = client.Get(path, {{"Authorization", "Bearer " + token}},
                           [&](const char* data, std::size_t n) {
                             buffer.append(data, n);
                             std::size_t end;
                             while ((end = buffer.find("\n\n")) != std::string::npos) {
                               std::string frame = buffer.substr(0, end);
                               buffer.erase(0, end + 2);
                               std::string event, data_line;
                               std::size_t pos = 0;
                               while (pos < frame.size()) {
                                 std::size_t eol = frame.find('\n', pos);
                                 if (eol == std::string::npos) eol = frame.size();
                                 std::string line = frame.substr(pos, eol - pos);
                                 if (line.rfind("event: ", 0) == 0) event = line.substr(7);
                                 if (line.rfind("data: ", 0) == 0) data_line = line.substr(6);
                                 pos = eol + 1;
                               }
                               if (!event.empty()) events.emplace_back(event, json::parse(data_line));
                             }
                             return true;
                           });
  EXPECT_TRUE(result) << "stream request failed";
  if (result) {
    EXPECT_EQ(result->status, 200);
    EXPECT_EQ(result->get_header_value("Content-Type"), "text/event-stream");
  }
  return events;
}

TEST(ApiFlowTest, RapidParameterisationEndToEnd) {
  ServerProcess server;
  auto client = server.Client();
  const std::string admin = server.admin_token();
  ASSERT_EQ(admin.rfind("fsb_", 0), 0u);
  struct stat st {};
  ASSERT_EQ(::stat((server.dir() / "data" / "admin.token").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  EXPECT_NE(server.output().find(admin), std::string::npos) << "the token is printed once";

  const std::string clinician = CreateUserToken(client, admin, "clara", "clinician");
  const std::string analyst = CreateUserToken(client, admin, "anton", "analyst");

  // The virtual subject: the seeded one with a known pole and limits.
  auto truth = Call(client, "GET", "/api/v1/bench/virtual-subject", admin);
  ASSERT_EQ(truth.status, 200) << truth.text;
  json subject_json = truth.body;
  subject_json["truth"]["contraction"]["pole_per_s"] = 22.0;
  subject_json["name"] = "flow-test";
  auto put = Call(client, "PUT", "/api/v1/bench/virtual-subject", admin, subject_json);
  ASSERT_EQ(put.status, 200) << put.text;
  auto again = Call(client, "GET", "/api/v1/bench/virtual-subject", admin);
  ASSERT_EQ(again.status, 200);
  EXPECT_EQ(again.body["name"], "flow-test");
  EXPECT_DOUBLE_EQ(again.body["truth"]["contraction"]["pole_per_s"].get<double>(), 22.0);
  const double threshold_ma = again.body["threshold_ma"];
  const double max_tolerated_ma = again.body["max_tolerated_ma"];
  const double mass_kg = again.body["anthropometrics"]["body_mass_kg"];
  const double shank_m = again.body["anthropometrics"]["shank_length_m"];

  // Subject and session.
  auto subject = Call(client, "POST", "/api/v1/subjects", clinician,
                      {{"code", "FLOW-01"},
                       {"details", {{"age_years", 34}, {"sex", "female"},
                                    {"weight_kg", mass_kg}, {"shank_length_cm", shank_m * 100}}},
                       {"legs", {"right"}}});
  ASSERT_EQ(subject.status, 201) << subject.text;
  const std::int64_t subject_id = subject.body["id"];
  auto session = Call(client, "POST", "/api/v1/subjects/" + std::to_string(subject_id) + "/sessions",
                      clinician,
                      {{"leg", "right"}, {"date", "2026-11-21"},
                       {"threshold_ma", threshold_ma}, {"max_tolerated_ma", max_tolerated_ma},
                       {"notes", "integration test"}});
  ASSERT_EQ(session.status, 201) << session.text;
  const std::int64_t session_id = session.body["id"];

  // An analyst waits for new parameter sets (sets as events). The
  // stream's one parameter is checked first.
  for (const char* bad : {"0", "3601", "abc"}) {
    auto refused = Call(client, "GET", std::string("/api/v1/events/parameter-sets?timeout_s=") + bad,
                        analyst);
    EXPECT_EQ(refused.status, 400) << bad;
    EXPECT_EQ(refused.body["error"]["field"], "timeout_s") << refused.text;
  }
  json set_event;
  std::thread set_watcher([&] {
    httplib::Client c("127.0.0.1", server.port());
    c.set_read_timeout(60);
    std::string buffer;
    c.Get("/api/v1/events/parameter-sets?timeout_s=60", {{"Authorization", "Bearer " + analyst}},
          [&](const char* data, std::size_t n) {
            buffer.append(data, n);
            const std::size_t at = buffer.find("event: parameter_set\ndata: ");
            if (at == std::string::npos) return true;
            const std::size_t from = at + std::string("event: parameter_set\ndata: ").size();
            const std::size_t eol = buffer.find('\n', from);
            if (eol == std::string::npos) return true;
            set_event = json::parse(buffer.substr(from, eol - from));
            return false;  // the first set is enough: leave
          });
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // subscribed

  // Start the run and follow its stream to the end, heart-beating meanwhile.
  auto run = Call(client, "POST", "/api/v1/sessions/" + std::to_string(session_id) + "/runs",
                  clinician, {{"protocol", "rapid_parameterisation"}});
  ASSERT_EQ(run.status, 201) << run.text;
  const std::int64_t run_id = run.body["run_id"];
  std::atomic<bool> streaming{true};
  std::thread heart([&] {
    auto hb = server.Client();
    while (streaming) {
      Call(hb, "POST", "/api/v1/runs/" + std::to_string(run_id) + "/heartbeat", clinician);
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
  });
  auto events = FollowStream(server.port(), "/api/v1/runs/" + std::to_string(run_id) + "/stream",
                             analyst);
  streaming = false;
  heart.join();
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.front().first, "state");
  ASSERT_EQ(events.back().first, "end");
  EXPECT_EQ(events.back().second["state"], "done") << events.back().second.dump();
  EXPECT_EQ(events.back().second["dropped"], 0);
  ASSERT_TRUE(events.back().second["parameter_set_id"].is_number_integer());
  const std::int64_t set_id = events.back().second["parameter_set_id"];
  set_watcher.join();
  ASSERT_TRUE(set_event.is_object()) << "no parameter_set event";
  EXPECT_EQ(set_event["kind"], "parameter_set");
  EXPECT_EQ(set_event["parameter_set_id"], set_id);
  EXPECT_EQ(set_event["subject_id"], subject_id);
  // Sample batches, if any arrived, continue each other without gaps.
  std::uint64_t next_sample = 0;
  bool first_batch = true;
  for (const auto& [name, data] : events) {
    if (name != "samples") continue;
    const std::uint64_t first = data["first_sample"];
    if (!first_batch) {
      EXPECT_EQ(first, next_sample);
    }
    first_batch = false;
    next_sample = first + data["samples"]["t_s"].size();
  }

  auto run_view = Call(client, "GET", "/api/v1/runs/" + std::to_string(run_id), analyst);
  ASSERT_EQ(run_view.status, 200);
  EXPECT_EQ(run_view.body["state"], "done");
  EXPECT_EQ(run_view.body["parameter_set_id"], set_id);
  // ramp, 2 × (hold, release), search, RB
  EXPECT_EQ(run_view.body["trial_ids"].size(), 7u);

  // The identified parameter set against the virtual subject (§7.4.1).
  auto set = Call(client, "GET", "/api/v1/parameter-sets/" + std::to_string(set_id), analyst);
  ASSERT_EQ(set.status, 200) << set.text;
  EXPECT_EQ(set.body["subject_id"], subject_id);
  const json& params = set.body["parameters"];
  const double pole = params["contraction"]["pole_per_s"];
  EXPECT_NEAR(pole, 22.0, 0.15 * 22.0) << "contraction pole";
  const double scale = params["active"]["torque_scale_nm"];
  const double true_scale = again.body["truth"]["active"]["torque_scale_nm"];
  EXPECT_GT(scale, 0.0);
  EXPECT_EQ(set.body["trial_ids"], run_view.body["trial_ids"]);
  (void)true_scale;

  // A prediction of the recorded random-binary trial with the new set.
  const std::int64_t rb_trial = run_view.body["trial_ids"].back();
  auto submitted = Call(client, "POST", "/api/v1/predictions", analyst,
                        {{"parameter_set_id", set_id}, {"trial_id", rb_trial}});
  ASSERT_EQ(submitted.status, 202) << submitted.text;
  json job = WaitForJob(client, analyst, submitted.body["id"]);
  ASSERT_EQ(job["state"], "done") << job.dump();
  const json& errors = job["result"]["errors"];
  ASSERT_TRUE(errors.is_object()) << job.dump().substr(0, 2000);
  EXPECT_TRUE(std::isfinite(errors["e_rms"].get<double>()));
  EXPECT_LT(errors["e_rms"].get<double>(), 10.0) << "angle prediction error, deg";

  // History.
  auto history = Call(client, "GET",
                      "/api/v1/parameter-sets?subject_id=" + std::to_string(subject_id) +
                          "&leg=right",
                      analyst);
  ASSERT_EQ(history.status, 200);
  ASSERT_EQ(history.body["items"].size(), 1u);
  EXPECT_EQ(history.body["items"][0]["id"], set_id);
  auto runs = Call(client, "GET", "/api/v1/sessions/" + std::to_string(session_id) + "/runs",
                   analyst);
  ASSERT_EQ(runs.status, 200);
  ASSERT_EQ(runs.body["items"].size(), 1u);
  EXPECT_EQ(runs.body["items"][0]["state"], "done");
  auto predictions = Call(client, "GET",
                          "/api/v1/parameter-sets/" + std::to_string(set_id) + "/predictions",
                          analyst);
  ASSERT_EQ(predictions.status, 200);
  EXPECT_EQ(predictions.body["items"].size(), 1u);
  auto audit = Call(client, "GET", "/api/v1/audit?limit=500", admin);
  ASSERT_EQ(audit.status, 200);
  bool subject_audited = false, session_audited = false, virtual_audited = false;
  for (const auto& entry : audit.body["items"]) {
    const std::string action = entry["action"];
    subject_audited |= action == "POST /api/v1/subjects" && entry["actor"] == "clara";
    session_audited |= action.find("/sessions") != std::string::npos && entry["actor"] == "clara";
    virtual_audited |= entry["actor"] == "admin" &&
                       entry["target"].get<std::string>().find("virtual") != std::string::npos;
  }
  EXPECT_TRUE(subject_audited);
  EXPECT_TRUE(session_audited);
  EXPECT_TRUE(virtual_audited) << audit.body.dump().substr(0, 3000);

  EXPECT_EQ(server.Terminate(), 0);
}

TEST(ApiFlowTest, PagingWalksEveryItemOnce) {
  ServerProcess server;
  auto client = server.Client();
  for (int i = 0; i < 7; ++i) {
    ASSERT_EQ(Call(client, "POST", "/api/v1/subjects", server.admin_token(),
                   {{"code", "P" + std::to_string(i)}})
                  .status,
              201);
  }
  std::vector<std::int64_t> seen;
  std::string path = "/api/v1/subjects?limit=3";
  for (int pages = 0; pages < 10; ++pages) {
    auto page = Call(client, "GET", path, server.admin_token());
    ASSERT_EQ(page.status, 200) << page.text;
    for (const auto& item : page.body["items"]) seen.push_back(item["id"]);
    if (page.body["next_cursor"].is_null()) break;
    path = "/api/v1/subjects?limit=3&cursor=" + page.body["next_cursor"].get<std::string>();
  }
  ASSERT_EQ(seen.size(), 7u);
  for (std::size_t i = 1; i < seen.size(); ++i) EXPECT_GT(seen[i], seen[i - 1]);
  EXPECT_EQ(server.Terminate(), 0);
}

TEST(ApiFlowTest, SigtermDuringRealTimeRunStopsSafely) {
  ServerProcess server({"--time-scale", "1"});
  auto client = server.Client();
  const std::string admin = server.admin_token();
  auto subject = Call(client, "POST", "/api/v1/subjects", admin, {{"code", "TERM-1"}});
  ASSERT_EQ(subject.status, 201);
  auto session = Call(client, "POST",
                      "/api/v1/subjects/" + std::to_string(subject.body["id"].get<int>()) +
                          "/sessions",
                      admin,
                      {{"leg", "left"}, {"date", "2026-11-21"}, {"threshold_ma", 15},
                       {"max_tolerated_ma", 40}});
  ASSERT_EQ(session.status, 201) << session.text;
  auto run = Call(client, "POST",
                  "/api/v1/sessions/" + std::to_string(session.body["id"].get<int>()) + "/runs",
                  admin, {{"protocol", "isometric_ramp_irc"}});
  ASSERT_EQ(run.status, 201) << run.text;
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  auto busy = Call(client, "POST",
                   "/api/v1/sessions/" + std::to_string(session.body["id"].get<int>()) + "/runs",
                   admin, {{"protocol", "isometric_ramp_irc"}});
  EXPECT_EQ(busy.status, 409) << busy.text;
  EXPECT_EQ(server.Terminate(), 0) << server.output();
  EXPECT_NE(server.output().find("stopped"), std::string::npos);

  // The database was closed cleanly: a new server on it reads the run as
  // ended (not running).
  auto again_ptr = ServerProcess::Restart(server);
  ServerProcess& again = *again_ptr;
  auto client2 = again.Client();
  auto stored = Call(client2, "GET", "/api/v1/runs/" + std::to_string(run.body["run_id"].get<int>()),
                     admin);
  ASSERT_EQ(stored.status, 200) << stored.text;
  EXPECT_NE(stored.body["state"], "running");
  EXPECT_NE(stored.body["state"], "queued");
  EXPECT_EQ(again.Terminate(), 0);
}

}  // namespace
}  // namespace fesbench::testing

namespace fesbench::testing {
namespace {

// Several viewers at once; a viewer that leaves frees its slot (and worker).
TEST(ApiFlowTest, StreamViewersShareAndALeavingViewerFreesItsSlot) {
  ServerProcess server({"--time-scale", "1", "--max-streams", "2"});
  auto client = server.Client();
  const std::string admin = server.admin_token();
  auto subject = Call(client, "POST", "/api/v1/subjects", admin, {{"code", "VIEW-1"}});
  ASSERT_EQ(subject.status, 201);
  auto session = Call(client, "POST", "/api/v1/subjects/1/sessions", admin,
                      {{"leg", "left"}, {"date", "2026-11-21"}, {"threshold_ma", 15},
                       {"max_tolerated_ma", 40}});
  ASSERT_EQ(session.status, 201);
  auto run = Call(client, "POST", "/api/v1/sessions/1/runs", admin,
                  {{"protocol", "isometric_ramp_irc"}});
  ASSERT_EQ(run.status, 201) << run.text;
  const std::string stream_path = "/api/v1/runs/" + std::to_string(run.body["run_id"].get<int>()) +
                                  "/stream";
  std::atomic<bool> beating{true};
  std::thread heart([&] {
    auto hb = server.Client();
    while (beating) {
      Call(hb, "POST", "/api/v1/runs/1/heartbeat", admin);
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
  });

  // Two viewers read at once; each leaves after its first samples.
  auto view_briefly = [&](std::atomic<int>& status) {
    httplib::Client c("127.0.0.1", server.port());
    std::size_t bytes = 0;
    auto r = c.Get(stream_path, {{"Authorization", "Bearer " + admin}},
                   [&](const httplib::Response& res) {
                     status = res.status;
                     return true;
                   },
                   [&](const char*, std::size_t n) {
                     bytes += n;
                     return bytes < 2000;  // leave after a few frames
                   });
    (void)r;
  };
  std::atomic<int> first{0}, second{0};
  std::thread a([&] { view_briefly(first); });
  std::thread b([&] { view_briefly(second); });
  a.join();
  b.join();
  EXPECT_EQ(first, 200);
  EXPECT_EQ(second, 200);

  // Both left: within a few seconds their slots are free again.
  int status = 0;
  for (int attempt = 0; attempt < 50 && status != 200; ++attempt) {
    std::atomic<int> third{0};
    view_briefly(third);
    status = third;
    if (status != 200) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_EQ(status, 200);
  beating = false;
  heart.join();
  EXPECT_EQ(server.Terminate(), 0);
}

}  // namespace
}  // namespace fesbench::testing
