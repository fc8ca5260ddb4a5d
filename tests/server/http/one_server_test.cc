// Integration (docs/SAFETY.md, "One server per bench" and "Files"): real
// fesbench-server processes. A second server on the same SQLite file is
// refused at start naming the file and the first server's pid, and the first
// server's run goes on untouched. On PostgreSQL a second server for a bench
// is refused, also after the first's lock connection was killed; the first
// then latches its e-stop and refuses runs until it holds the bench again,
// or, when another session took the bench meanwhile, stops and exits
// non-zero. What the server creates is 0600/0700 under umask 022.

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <string>
#include <thread>

#include "server_process.h"
#include "storage/bench_lock.h"
#include "storage/postgres_connection.h"
#include "tests/support/postgres_server.h"

namespace fesbench::testing {
namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

mode_t ModeOf(const std::filesystem::path& path) {
  struct stat info {};
  EXPECT_EQ(::stat(path.c_str(), &info), 0) << path;
  return info.st_mode & 07777;
}

// A subject with a right leg and a session with the bench's virtual
// subject's tolerance values; returns the session id.
std::int64_t MakeSession(httplib::Client& client, const std::string& admin,
                         const std::string& code) {
  auto truth = Call(client, "GET", "/api/v1/bench/virtual-subject", admin);
  EXPECT_EQ(truth.status, 200) << truth.text;
  auto subject = Call(
      client, "POST", "/api/v1/subjects", admin,
      {{"code", code},
       {"details",
        {{"weight_kg", truth.body["anthropometrics"]["body_mass_kg"]},
         {"shank_length_cm", truth.body["anthropometrics"]["shank_length_m"].get<double>() * 100}}},
       {"legs", {"right"}}});
  EXPECT_EQ(subject.status, 201) << subject.text;
  auto session =
      Call(client, "POST", "/api/v1/subjects/" + subject.body["id"].dump() + "/sessions", admin,
           {{"leg", "right"},
            {"date", "2026-11-27"},
            {"threshold_ma", truth.body["threshold_ma"]},
            {"max_tolerated_ma", truth.body["max_tolerated_ma"]}});
  EXPECT_EQ(session.status, 201) << session.text;
  return session.body["id"];
}

JsonResponse StartRun(httplib::Client& client, const std::string& token, std::int64_t session) {
  return Call(client, "POST", "/api/v1/sessions/" + std::to_string(session) + "/runs", token,
              {{"protocol", "rapid_parameterisation"}});
}

// Heartbeats for `run_id` until destroyed (the watchdog would end it).
class Heartbeats {
 public:
  Heartbeats(const ServerProcess& server, const std::string& token, std::int64_t run_id)
      : thread_([this, &server, token, run_id] {
          auto client = server.Client();
          const std::string path = "/api/v1/runs/" + std::to_string(run_id) + "/heartbeat";
          while (!stop_) {
            Call(client, "POST", path, token);
            std::this_thread::sleep_for(std::chrono::milliseconds(200));
          }
        }) {}
  ~Heartbeats() {
    stop_ = true;
    thread_.join();
  }

 private:
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

std::string RunState(httplib::Client& client, const std::string& token, std::int64_t run_id) {
  return Call(client, "GET", "/api/v1/runs/" + std::to_string(run_id), token)
      .body.value("state", "");
}

TEST(OneServerTest, ASecondServerOnTheSqliteFileIsRefusedAndTheFirstRunGoesOn) {
  ServerProcess first({"--time-scale", "20"});
  auto client = first.Client();
  const std::int64_t session = MakeSession(client, first.admin_token(), "ONE-1");
  auto run = StartRun(client, first.admin_token(), session);
  ASSERT_EQ(run.status, 201) << run.text;
  const std::int64_t run_id = run.body["run_id"];
  Heartbeats heartbeats(first, first.admin_token(), run_id);

  const ExitedServer second = RunServerToExit({"--port", "0", "--db", first.db_path().string(),
                                               "--data-dir", (first.dir() / "data").string(),
                                               "--time-scale", "0", "--dds-transport", "off"});
  std::printf("second server on the same SQLite file: exit %d after %.0f ms\n", second.exit_code,
              second.elapsed_ms);
  EXPECT_EQ(second.exit_code, 1) << second.output << second.error;
  EXPECT_NE(second.error.find("'" + first.db_path().string() + "'"), std::string::npos)
      << second.error;
  EXPECT_NE(second.error.find("pid " + std::to_string(first.pid())), std::string::npos)
      << second.error;
  EXPECT_EQ(second.output.find("listening"), std::string::npos) << second.output;
  EXPECT_EQ(second.output.find("left unfinished"), std::string::npos) << second.output;

  // The first server's run went on: still its own, never marked failed.
  const std::string state = RunState(client, first.admin_token(), run_id);
  EXPECT_TRUE(state == "running" || state == "queued" || state == "done") << state;
  std::string final_state = state;
  const auto t0 = Clock::now();
  while ((final_state == "running" || final_state == "queued") &&
         Clock::now() - t0 < std::chrono::minutes(3)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    final_state = RunState(client, first.admin_token(), run_id);
  }
  EXPECT_EQ(final_state, "done");
  auto bench = Call(client, "GET", "/api/v1/bench", first.admin_token());
  EXPECT_EQ(bench.body.value("estopped", true), false) << bench.text;
}

TEST(OneServerTest, WhatTheServerCreatesIsTheOwnersOnlyUnderUmask022) {
  const mode_t old_mask = ::umask(022);
  ServerProcess server;
  ::umask(old_mask);
  auto client = server.Client();
  ASSERT_EQ(Call(client, "POST", "/api/v1/subjects", server.admin_token(), {{"code", "F1"}}).status,
            201);
  auto backup = Call(client, "POST", "/api/v1/backup", server.admin_token());
  ASSERT_EQ(backup.status, 201) << backup.text;

  const auto data = server.dir() / "data";
  const std::string db = server.db_path().string();
  EXPECT_EQ(ModeOf(data), 0700u);
  EXPECT_EQ(ModeOf(db), 0600u);
  EXPECT_EQ(ModeOf(db + "-wal"), 0600u);
  EXPECT_EQ(ModeOf(db + "-shm"), 0600u);
  EXPECT_EQ(ModeOf(db + ".lock"), 0600u);
  EXPECT_EQ(ModeOf(data / "admin.token"), 0600u);
  EXPECT_EQ(ModeOf(data / "backups"), 0700u);
  EXPECT_EQ(ModeOf(backup.body["path"].get<std::string>()), 0600u);
  std::printf(
      "modes under umask 022: data/ %04o, fesbench.db %04o, -wal %04o, -shm %04o, "
      ".lock %04o, admin.token %04o, backups/ %04o, backup %04o\n",
      ModeOf(data), ModeOf(db), ModeOf(db + "-wal"), ModeOf(db + "-shm"), ModeOf(db + ".lock"),
      ModeOf(data / "admin.token"), ModeOf(data / "backups"),
      ModeOf(backup.body["path"].get<std::string>()));
}

// --- PostgreSQL ----------------------------------------------------------------------

// Ends the connection holding `bench_id`'s lock, as an idle-session killer
// or a failover would; the number of connections ended.
std::string KillLockConnection(const std::string& url, const std::string& bench_id) {
  auto conn = storage::PostgresConnection::Open(url);
  if (!conn.ok()) return conn.status().ToString();
  auto ended = (*conn)->QueryText(
      "SELECT count(pg_terminate_backend(pid)) FROM pg_stat_activity"
      " WHERE datname = current_database() AND application_name = '" +
      storage::PostgresBenchLock::ApplicationName(bench_id) + "'");
  return ended.ok() ? *ended : ended.status().ToString();
}

std::vector<std::string> ServerArgs(const std::string& url, const std::string& bench_id) {
  return {"--port",          "0",  "--db", url, "--bench-id", bench_id, "--time-scale", "20",
          "--dds-transport", "off"};
}

#define SKIP_WITHOUT_POSTGRES(database)                                   \
  if (!(database).ok()) {                                                 \
    if ((database).skippable()) GTEST_SKIP() << (database).skip_reason(); \
    FAIL() << (database).skip_reason();                                   \
  }

TEST(OneServerTest, OnPostgresTheFirstServerLatchesAndRefusesRunsWhileItsLockIsLost) {
  ScratchDatabase database;
  SKIP_WITHOUT_POSTGRES(database);
  ServerProcess first({"--db", database.url(), "--bench-id", "knee-a", "--time-scale", "20"});
  const std::string admin = first.admin_token();
  auto client = first.Client();
  const std::int64_t session = MakeSession(client, admin, "PG-1");

  const ExitedServer refused = RunServerToExit(ServerArgs(database.url(), "knee-a"));
  EXPECT_EQ(refused.exit_code, 1) << refused.output << refused.error;
  EXPECT_NE(refused.error.find("bench 'knee-a'"), std::string::npos) << refused.error;

  auto run = StartRun(client, admin, session);
  ASSERT_EQ(run.status, 201) << run.text;
  const std::int64_t run_id = run.body["run_id"];
  std::optional<Heartbeats> heartbeats(std::in_place, first, admin, run_id);

  const auto killed_at = Clock::now();
  ASSERT_EQ(KillLockConnection(database.url(), "knee-a"), "1");
  double latched_ms = -1;
  while (MsSince(killed_at) < 10000) {
    auto bench = Call(client, "GET", "/api/v1/bench", admin);
    if (bench.body.value("estopped", false)) {
      latched_ms = MsSince(killed_at);
      break;
    }
  }
  ASSERT_GE(latched_ms, 0) << "the e-stop never latched";
  heartbeats.reset();
  // The latch is immediate; the run ends at its next control period and
  // reads final once its end is stored (a few ms idle, longer under a
  // sanitizer on a loaded machine).
  std::string ended = RunState(client, admin, run_id);
  while ((ended == "running" || ended == "queued") && MsSince(killed_at) < 20000) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    ended = RunState(client, admin, run_id);
  }
  const double ended_ms = MsSince(killed_at);
  EXPECT_TRUE(ended == "aborted" || ended == "failed") << ended;

  // Refused while lost; regained ~250 ms later (nobody else took it): a
  // second server is refused again, and runs start once the e-stop is cleared.
  auto during = StartRun(client, admin, session);
  std::printf(
      "lock connection killed: e-stop latched after %.1f ms, the run %s after %.1f ms; a run "
      "start then: %d\n",
      latched_ms, ended.c_str(), ended_ms, during.status);
  if (during.status == 503) {
    EXPECT_NE(during.text.find("lock on bench 'knee-a'"), std::string::npos) << during.text;
  } else {
    EXPECT_EQ(during.status, 409) << during.text;  // lock back already: the e-stop refuses it
  }
  EXPECT_NE(first.Stderr().find("lost the lock on bench 'knee-a'"), std::string::npos)
      << first.Stderr();
  const auto t0 = Clock::now();
  while (first.Stderr().find("holds bench 'knee-a' again") == std::string::npos &&
         MsSince(t0) < 10000) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_NE(first.Stderr().find("holds bench 'knee-a' again"), std::string::npos) << first.Stderr();
  const ExitedServer after = RunServerToExit(ServerArgs(database.url(), "knee-a"));
  EXPECT_EQ(after.exit_code, 1) << after.output << after.error;
  EXPECT_NE(after.error.find("bench 'knee-a'"), std::string::npos) << after.error;

  auto cleared = Call(client, "DELETE", "/api/v1/bench/estop", admin);
  EXPECT_EQ(cleared.status, 200) << cleared.text;
  auto again = StartRun(client, admin, session);
  EXPECT_EQ(again.status, 201) << again.text;
  if (again.status == 201) {
    Call(client, "POST", "/api/v1/runs/" + again.body["run_id"].dump() + "/cancel", admin);
  }
}

TEST(OneServerTest, OnPostgresABenchTakenWhileTheLockIsLostStopsTheFirstServer) {
  ScratchDatabase database;
  SKIP_WITHOUT_POSTGRES(database);
  auto first = std::make_unique<ServerProcess>(std::vector<std::string>{
      "--db", database.url(), "--bench-id", "knee-a", "--time-scale", "20"});
  const std::string admin = first->admin_token();
  auto client = first->Client();
  const std::int64_t session = MakeSession(client, admin, "PG-2");
  auto run = StartRun(client, admin, session);
  ASSERT_EQ(run.status, 201) << run.text;
  const std::int64_t run_id = run.body["run_id"];
  std::optional<Heartbeats> heartbeats(std::in_place, *first, admin, run_id);

  // Another session waits for the bench's lock and gets it the moment the
  // first server's lock connection ends, before the first can take it back.
  auto rival = storage::PostgresConnection::Open(database.url());
  ASSERT_TRUE(rival.ok()) << rival.status().ToString();
  std::thread take([&] {
    (void)(*rival)->QueryText("SELECT pg_advisory_lock(hashtext('fesbench bench knee-a'))");
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // waiting in the lock queue
  const auto killed_at = Clock::now();
  ASSERT_EQ(KillLockConnection(database.url(), "knee-a"), "1");
  take.join();
  const std::optional<int> exit_code = first->AwaitExit(std::chrono::seconds(20));
  const double exit_ms = MsSince(killed_at);
  heartbeats.reset();
  ASSERT_TRUE(exit_code.has_value()) << "the first server still serves beside the new holder";
  EXPECT_EQ(*exit_code, 1);
  const std::string err = first->Stderr();
  std::printf("bench taken while the lock was lost: the first server exited %d after %.0f ms\n",
              *exit_code, exit_ms);
  EXPECT_NE(err.find("lost the lock on bench 'knee-a'"), std::string::npos) << err;
  EXPECT_NE(err.find("bench 'knee-a' is now held by"), std::string::npos) << err;

  // The rival lets go; a new server takes the bench and finds the run ended
  // by the e-stop (stored by the first server), and the latch set.
  rival->reset();
  ServerProcess second({"--db", database.url(), "--bench-id", "knee-a"});
  auto second_client = second.Client();
  const std::string state = RunState(second_client, admin, run_id);
  EXPECT_TRUE(state == "aborted" || state == "failed") << state;
  auto bench = Call(second_client, "GET", "/api/v1/bench", admin);
  EXPECT_TRUE(bench.body.value("estopped", false)) << bench.text;
}

}  // namespace
}  // namespace fesbench::testing
