// Integration (docs/SAFETY.md, "One server per bench"): two fesbench-servers, each with its own
// simulated bench, on one PostgreSQL database. Both run rapid_parameterisation at the
// same time while analysts list and fetch through either server, and an
// analyst on one server receives both benches' new sets as events. Each run
// is its own bench's: the other server sees it and its parameter set but
// will not move it, and a second server for a bench already served is
// refused at start.

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "server_process.h"
#include "tests/support/postgres_server.h"

namespace fesbench::testing {
namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

double Ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

double Percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  return values[static_cast<std::size_t>(p * static_cast<double>(values.size() - 1))];
}

// A subject with a right leg and a session whose tolerance values are the
// bench's virtual subject's; returns the session id.
std::int64_t MakeBenchSession(httplib::Client& client, const std::string& admin,
                         const std::string& token, const std::string& code) {
  auto truth = Call(client, "GET", "/api/v1/bench/virtual-subject", admin);
  EXPECT_EQ(truth.status, 200) << truth.text;
  auto subject = Call(client, "POST", "/api/v1/subjects", token,
                      {{"code", code},
                       {"details", {{"sex", "female"},
                                    {"weight_kg", truth.body["anthropometrics"]["body_mass_kg"]},
                                    {"shank_length_cm",
                                     truth.body["anthropometrics"]["shank_length_m"].get<double>() *
                                         100}}},
                       {"legs", {"right"}}});
  EXPECT_EQ(subject.status, 201) << subject.text;
  auto session = Call(client, "POST",
                      "/api/v1/subjects/" + subject.body["id"].dump() + "/sessions", token,
                      {{"leg", "right"},
                       {"date", "2026-11-25"},
                       {"threshold_ma", truth.body["threshold_ma"]},
                       {"max_tolerated_ma", truth.body["max_tolerated_ma"]}});
  EXPECT_EQ(session.status, 201) << session.text;
  return session.body["id"];
}

TEST(TwoBenchesTest, TwoServersOnOnePostgresRunAtOnceAndSeeEachOther) {
  ScratchDatabase database;
  if (!database.ok()) {
    if (database.skippable()) GTEST_SKIP() << database.skip_reason();
    FAIL() << database.skip_reason();
  }
  // Time scale 20: the runs last seconds, so the analysts work beside them.
  ServerProcess a(
      {"--db", database.url(), "--bench-id", "knee-a", "--seed", "3", "--time-scale", "20"});
  ServerProcess b(
      {"--db", database.url(), "--bench-id", "knee-b", "--seed", "8", "--time-scale", "20"});
  EXPECT_NE(a.output().find("bench id knee-a"), std::string::npos) << a.output();
  // Only the first server to meet an empty database creates the admin.
  const std::string admin = !a.admin_token().empty() ? a.admin_token() : b.admin_token();
  ASSERT_FALSE(admin.empty());

  // One server per bench: a second one for knee-a does not start.
  EXPECT_THROW(ServerProcess({"--db", database.url(), "--bench-id", "knee-a"},
                             std::chrono::seconds(10)),
               std::runtime_error);

  auto client_a = a.Client();
  auto client_b = b.Client();
  const std::string clinician = CreateUserToken(client_a, admin, "clara", "clinician");
  const std::string analyst = CreateUserToken(client_b, admin, "anton", "analyst");
  const std::int64_t session_a = MakeBenchSession(client_a, admin, clinician, "TWO-A");
  const std::int64_t session_b = MakeBenchSession(client_b, admin, clinician, "TWO-B");

  // Analysts list and fetch on both servers while the runs go.
  std::atomic<bool> running{true};
  std::atomic<int> analyst_errors{0};
  std::vector<double> list_ms, fetch_ms;
  std::thread analysts([&] {
    auto on_a = a.Client();
    auto on_b = b.Client();
    int turn = 0;
    while (running) {
      httplib::Client& c = (turn++ % 2 == 0) ? on_a : on_b;
      const auto t0 = Clock::now();
      auto sets = Call(c, "GET", "/api/v1/parameter-sets?limit=50", analyst);
      auto subjects = Call(c, "GET", "/api/v1/subjects?limit=50", analyst);
      list_ms.push_back(Ms(Clock::now() - t0) / 2);
      if (sets.status != 200 || subjects.status != 200) ++analyst_errors;
      for (const auto& item : subjects.body.value("items", json::array())) {
        const auto t1 = Clock::now();
        auto one = Call(c, "GET", "/api/v1/subjects/" + item["id"].dump(), analyst);
        fetch_ms.push_back(Ms(Clock::now() - t1));
        if (one.status != 200) ++analyst_errors;
      }
      for (const auto& item : sets.body.value("items", json::array())) {
        const auto t1 = Clock::now();
        auto one = Call(c, "GET", "/api/v1/parameter-sets/" + item["id"].dump(), analyst);
        fetch_ms.push_back(Ms(Clock::now() - t1));
        if (one.status != 200) ++analyst_errors;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  });

  // An analyst on server B waits for new sets: both benches' arrive (A's
  // through PostgreSQL's NOTIFY), each once.
  std::vector<std::int64_t> events_on_b;
  std::mutex events_mutex;
  std::thread watcher([&] {
    httplib::Client c("127.0.0.1", b.port());
    c.set_read_timeout(120);
    std::string buffer;
    const std::string marker = "event: parameter_set\ndata: ";
    c.Get("/api/v1/events/parameter-sets?timeout_s=120", {{"Authorization", "Bearer " + analyst}},
          [&](const char* data, std::size_t n) {
            buffer.append(data, n);
            std::size_t at;
            while ((at = buffer.find(marker)) != std::string::npos) {
              const std::size_t eol = buffer.find('\n', at + marker.size());
              if (eol == std::string::npos) return true;
              const json event = json::parse(buffer.substr(at + marker.size(), eol - at - marker.size()));
              buffer.erase(0, eol);
              std::lock_guard lock(events_mutex);
              events_on_b.push_back(event["parameter_set_id"]);
              if (events_on_b.size() == 2) return false;
            }
            return true;
          });
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // subscribed

  struct Bench {
    ServerProcess* server = nullptr;
    std::int64_t session = 0;
    std::int64_t run_id = 0;
    json view;
    double seconds = 0;
  };
  std::vector<Bench> benches(2);
  benches[0].server = &a;
  benches[0].session = session_a;
  benches[1].server = &b;
  benches[1].session = session_b;
  for (auto& bench : benches) {
    auto c = bench.server->Client();
    auto run = Call(c, "POST", "/api/v1/sessions/" + std::to_string(bench.session) + "/runs",
                    clinician, {{"protocol", "rapid_parameterisation"}});
    ASSERT_EQ(run.status, 201) << run.text;
    bench.run_id = run.body["run_id"];
  }
  // The other server sees each run but does not move it.
  auto foreign = Call(client_b, "POST", "/api/v1/runs/" + std::to_string(benches[0].run_id) + "/cancel",
                      clinician);
  EXPECT_EQ(foreign.status, 409) << foreign.text;
  EXPECT_NE(foreign.text.find("knee-a"), std::string::npos) << foreign.text;

  std::vector<std::thread> drivers;
  for (auto& bench : benches) {
    drivers.emplace_back([&bench, &clinician] {
      auto c = bench.server->Client();
      const auto t0 = Clock::now();
      const std::string path = "/api/v1/runs/" + std::to_string(bench.run_id);
      while (Clock::now() - t0 < std::chrono::minutes(3)) {
        Call(c, "POST", path + "/heartbeat", clinician);
        bench.view = Call(c, "GET", path, clinician).body;
        if (bench.view.value("state", "") != "queued" && bench.view.value("state", "") != "running") {
          break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(200));
      }
      bench.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    });
  }
  for (auto& t : drivers) t.join();
  running = false;
  analysts.join();

  for (const auto& bench : benches) {
    ASSERT_EQ(bench.view.value("state", ""), "done") << bench.view.dump().substr(0, 2000);
    ASSERT_TRUE(bench.view["parameter_set_id"].is_number_integer());
  }
  EXPECT_EQ(analyst_errors.load(), 0);
  watcher.join();
  {
    std::lock_guard lock(events_mutex);
    std::vector<std::int64_t> expected = {benches[0].view["parameter_set_id"],
                                          benches[1].view["parameter_set_id"]};
    std::sort(expected.begin(), expected.end());
    std::sort(events_on_b.begin(), events_on_b.end());
    EXPECT_EQ(events_on_b, expected) << "server B's event stream";
  }

  // Each server's analysts see both benches' runs and sets.
  for (httplib::Client* c : {&client_a, &client_b}) {
    auto sets = Call(*c, "GET", "/api/v1/parameter-sets?limit=50", analyst);
    ASSERT_EQ(sets.status, 200);
    std::vector<std::int64_t> ids;
    for (const auto& item : sets.body["items"]) ids.push_back(item["id"]);
    for (const auto& bench : benches) {
      EXPECT_NE(std::find(ids.begin(), ids.end(), bench.view["parameter_set_id"].get<std::int64_t>()),
                ids.end());
      auto run = Call(*c, "GET", "/api/v1/runs/" + std::to_string(bench.run_id), analyst);
      ASSERT_EQ(run.status, 200);
      EXPECT_EQ(run.body["state"], "done");
    }
  }
  // One audit sequence: ids unique and in order on either server.
  auto audit = Call(client_a, "GET", "/api/v1/audit?limit=500", admin);
  ASSERT_EQ(audit.status, 200);
  std::vector<std::int64_t> audit_ids;
  for (const auto& entry : audit.body["items"]) audit_ids.push_back(entry["id"]);
  EXPECT_TRUE(std::is_sorted(audit_ids.rbegin(), audit_ids.rend()));
  EXPECT_EQ(std::adjacent_find(audit_ids.begin(), audit_ids.end()), audit_ids.end());

  std::printf(
      "two benches on one PostgreSQL: runs %.1f s and %.1f s side by side; analysts during them: "
      "%zu list pages p50 %.1f ms p99 %.1f ms, %zu fetches p50 %.1f ms p99 %.1f ms\n",
      benches[0].seconds, benches[1].seconds, list_ms.size(), Percentile(list_ms, 0.5),
      Percentile(list_ms, 0.99), fetch_ms.size(), Percentile(fetch_ms, 0.5),
      Percentile(fetch_ms, 0.99));
  EXPECT_EQ(a.Terminate(), 0);
  EXPECT_EQ(b.Terminate(), 0);
}

}  // namespace
}  // namespace fesbench::testing
