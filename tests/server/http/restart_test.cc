// Restarts (docs/SAFETY.md, "Shutdown and restart") against the real fesbench-server process: the
// e-stop latch survives SIGTERM and SIGKILL until a person clears it (audited), and a run
// cut by SIGKILL is closed at the next start (failed, "server stopped during
// the run", audited) with the trials it stored still readable.

#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "server_process.h"

namespace fesbench::testing {
namespace {

using nlohmann::json;
using namespace std::chrono_literals;

bool EStopped(ServerProcess& server) {
  auto client = server.Client();
  auto bench = Call(client, "GET", "/api/v1/bench", server.admin_token());
  EXPECT_EQ(bench.status, 200) << bench.text;
  return bench.body.value("estopped", false);
}

// The audit rows with `action`, newest first.
std::vector<json> AuditRows(ServerProcess& server, const std::string& action) {
  auto client = server.Client();
  auto page = Call(client, "GET", "/api/v1/audit?limit=500", server.admin_token());
  EXPECT_EQ(page.status, 200) << page.text;
  std::vector<json> out;
  for (const json& e : page.body["items"]) {
    if (e["action"] == action) out.push_back(e);
  }
  return out;
}

std::int64_t MakeSession(httplib::Client& client, const std::string& token, const char* code) {
  auto truth = Call(client, "GET", "/api/v1/bench/virtual-subject", token);
  EXPECT_EQ(truth.status, 200) << truth.text;
  const double mass_kg = truth.body["anthropometrics"]["body_mass_kg"];
  const double shank_m = truth.body["anthropometrics"]["shank_length_m"];
  auto subject = Call(
      client, "POST", "/api/v1/subjects", token,
      {{"code", code},
       {"details", {{"sex", "female"}, {"weight_kg", mass_kg}, {"shank_length_cm", shank_m * 100}}},
       {"legs", {"right"}}});
  EXPECT_EQ(subject.status, 201) << subject.text;
  auto session = Call(client, "POST",
                      "/api/v1/subjects/" + std::to_string(subject.body["id"].get<int>()) +
                          "/sessions",
                      token,
                      {{"leg", "right"},
                       {"date", "2026-11-21"},
                       {"threshold_ma", truth.body["threshold_ma"]},
                       {"max_tolerated_ma", truth.body["max_tolerated_ma"]}});
  EXPECT_EQ(session.status, 201) << session.text;
  return session.body["id"];
}

TEST(RestartTest, TheEStopLatchSurvivesSigtermAndSigkillUntilAPersonClearsIt) {
  auto first = std::make_unique<ServerProcess>();
  const std::string admin = first->admin_token();
  std::string clinician;
  std::int64_t session_id = 0;
  {
    auto client = first->Client();
    clinician = CreateUserToken(client, admin, "clara", "clinician");
    session_id = MakeSession(client, admin, "LATCH-1");
    ASSERT_EQ(Call(client, "POST", "/api/v1/bench/estop", clinician).status, 200);
  }
  ASSERT_TRUE(EStopped(*first));
  const std::string start_path = "/api/v1/sessions/" + std::to_string(session_id) + "/runs";
  const json tolerance = {{"protocol", "tolerance_test"},
                          {"parameters", {{"settle_s", 0.2}, {"rate_ma_per_s", 5.0}}}};

  // SIGTERM: a clean stop keeps the latch.
  ASSERT_EQ(first->Terminate(), 0) << first->output();
  auto second = ServerProcess::Restart(*first);
  EXPECT_TRUE(EStopped(*second)) << "latched again after SIGTERM";
  EXPECT_NE(second->output().find("e-stop still latched"), std::string::npos)
      << second->output();
  {
    auto client = second->Client();
    auto refused = Call(client, "POST", start_path, clinician, tolerance);
    EXPECT_EQ(refused.status, 409) << refused.text;
  }

  // SIGKILL: a crash keeps it too.
  second->Kill();
  auto third = ServerProcess::Restart(*first);
  EXPECT_TRUE(EStopped(*third)) << "latched again after SIGKILL";
  EXPECT_EQ(AuditRows(*third, "bench.estop_restored").size(), 2u);
  EXPECT_TRUE(AuditRows(*third, "bench.clear_estop").empty()) << "nobody cleared it";

  // A person clears it (audited); that too survives a crash.
  {
    auto client = third->Client();
    ASSERT_EQ(Call(client, "DELETE", "/api/v1/bench/estop", clinician).status, 200);
  }
  EXPECT_FALSE(EStopped(*third));
  auto cleared = AuditRows(*third, "bench.clear_estop");
  ASSERT_EQ(cleared.size(), 1u);
  EXPECT_EQ(cleared[0]["actor"], "clara");
  third->Kill();
  auto fourth = ServerProcess::Restart(*first);
  EXPECT_FALSE(EStopped(*fourth));
  {
    auto client = fourth->Client();
    auto run = Call(client, "POST", start_path, clinician, tolerance);
    EXPECT_EQ(run.status, 201) << run.text;
  }
  EXPECT_EQ(fourth->Terminate(), 0);
}

TEST(RestartTest, ARunCutBySigkillIsClosedAtTheNextStartWithItsTrialsReadable) {
  // Twice real time: the rapid routine's first trial (7 s) is stored after
  // about 3.5 s, the whole run would take about 15 s.
  auto first = std::make_unique<ServerProcess>(std::vector<std::string>{"--time-scale", "2"});
  const std::string admin = first->admin_token();
  auto client = first->Client();
  const std::string clinician = CreateUserToken(client, admin, "clara", "clinician");
  const std::int64_t session_id = MakeSession(client, admin, "CRASH-1");
  auto run = Call(client, "POST", "/api/v1/sessions/" + std::to_string(session_id) + "/runs",
                  clinician, {{"protocol", "rapid_parameterisation"}});
  ASSERT_EQ(run.status, 201) << run.text;
  const std::int64_t run_id = run.body["run_id"];
  const std::string run_path = "/api/v1/runs/" + std::to_string(run_id);

  // Heart-beat until the run has stored a trial and is still running.
  json trial_ids;
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  while (std::chrono::steady_clock::now() < deadline) {
    Call(client, "POST", run_path + "/heartbeat", clinician);
    auto view = Call(client, "GET", run_path, clinician);
    ASSERT_EQ(view.status, 200) << view.text;
    ASSERT_TRUE(view.body["state"] == "running" || view.body["state"] == "queued") << view.text;
    if (!view.body["trial_ids"].empty() && view.body["state"] == "running") {
      trial_ids = view.body["trial_ids"];
      break;
    }
    std::this_thread::sleep_for(100ms);
  }
  ASSERT_FALSE(trial_ids.is_null()) << "no trial stored within 60 s";
  first->Kill();

  auto second = ServerProcess::Restart(*first);
  EXPECT_NE(second->output().find("run " + std::to_string(run_id) + " was left unfinished"),
            std::string::npos)
      << second->output();
  auto client2 = second->Client();
  auto stored = Call(client2, "GET", run_path, clinician);
  ASSERT_EQ(stored.status, 200) << stored.text;
  EXPECT_EQ(stored.body["state"], "failed");
  EXPECT_EQ(stored.body["reason"], "server stopped during the run");
  EXPECT_FALSE(stored.body["live"].get<bool>());
  ASSERT_GE(stored.body["trial_ids"].size(), trial_ids.size());
  for (const json& id : trial_ids) {
    auto trial = Call(client2, "GET", "/api/v1/trials/" + std::to_string(id.get<int>()), clinician);
    EXPECT_EQ(trial.status, 200) << trial.text;
  }
  auto recovered = AuditRows(*second, "run.recovered");
  ASSERT_EQ(recovered.size(), 1u);
  EXPECT_EQ(recovered[0]["actor"], "system");
  EXPECT_EQ(recovered[0]["target"], "runs/" + std::to_string(run_id));

  // The bench is free again: a new run starts.
  auto next = Call(client2, "POST", "/api/v1/sessions/" + std::to_string(session_id) + "/runs",
                   clinician,
                   {{"protocol", "tolerance_test"},
                    {"parameters", {{"settle_s", 0.2}, {"rate_ma_per_s", 5.0}}}});
  EXPECT_EQ(next.status, 201) << next.text;
  // A second restart finds nothing more to close.
  EXPECT_EQ(second->Terminate(), 0);
  auto third = ServerProcess::Restart(*first);
  EXPECT_EQ(AuditRows(*third, "run.recovered").size(), 1u);
  EXPECT_EQ(third->Terminate(), 0);
}

}  // namespace
}  // namespace fesbench::testing
