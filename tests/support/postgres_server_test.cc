// The tests' PostgreSQL server itself (tests/support): the shared server
// answers, scratch databases come and go, a server of one's own starts and
// stops.

#include "tests/support/postgres_server.h"

#include <gtest/gtest.h>
#include <libpq-fe.h>
#include <unistd.h>

#include <filesystem>
#include <regex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "tests/support/postgres_gtest.h"

namespace fesbench::testing {
namespace {

// The rows of `sql` on `url` (each a list of column texts), or the error.
struct PgTestRows {
  std::vector<std::vector<std::string>> rows;
  std::string error;
};

PgTestRows PgTestQuery(const std::string& url, const std::string& sql) {
  PgTestRows out;
  PGconn* conn = PQconnectdb((url + "?connect_timeout=5").c_str());
  if (PQstatus(conn) != CONNECTION_OK) {
    out.error = PQerrorMessage(conn);
    PQfinish(conn);
    return out;
  }
  PGresult* result = PQexec(conn, sql.c_str());
  const ExecStatusType status = PQresultStatus(result);
  if (status == PGRES_TUPLES_OK) {
    for (int row = 0; row < PQntuples(result); ++row) {
      std::vector<std::string> columns;
      for (int column = 0; column < PQnfields(result); ++column) {
        columns.emplace_back(PQgetvalue(result, row, column));
      }
      out.rows.push_back(std::move(columns));
    }
  } else if (status != PGRES_COMMAND_OK) {
    out.error = PQerrorMessage(conn);
  }
  PQclear(result);
  PQfinish(conn);
  return out;
}

int PgTestDatabaseCount(const std::string& base_url, const std::string& name) {
  const PgTestRows rows = PgTestQuery(
      base_url + "postgres", "SELECT count(*) FROM pg_database WHERE datname = '" + name + "'");
  EXPECT_EQ(rows.error, "");
  return rows.rows.empty() ? -1 : std::stoi(rows.rows[0][0]);
}

#define FESBENCH_SHARED_POSTGRES_OR_SKIP(shared)                         \
  const SharedPostgres& shared = SharedPostgresServer();                 \
  if ((shared).base_url.empty()) {                                       \
    if ((shared).binaries_missing) GTEST_SKIP() << (shared).skip_reason; \
    FAIL() << (shared).skip_reason;                                      \
  }

TEST(PostgresServerTest, SharedServerAnswers) {
  FESBENCH_SHARED_POSTGRES_OR_SKIP(shared);
  EXPECT_TRUE(std::regex_match(shared.base_url,
                               std::regex(R"(postgresql://postgres@127\.0\.0\.1:\d+/)")))
      << shared.base_url;
  const PgTestRows rows = PgTestQuery(shared.base_url + "postgres", "SELECT version()");
  ASSERT_EQ(rows.error, "");
  ASSERT_EQ(rows.rows.size(), 1u);
  EXPECT_EQ(rows.rows[0][0].rfind("PostgreSQL ", 0), 0u) << rows.rows[0][0];
  // The same server for every caller in the process.
  EXPECT_EQ(&SharedPostgresServer(), &shared);
}

TEST(ScratchDatabaseTest, CreatesUsesAndDrops) {
  const std::string base_url = SharedPostgresServer().base_url;
  std::string name;
  {
    ScratchDatabase db;
    FESBENCH_SKIP_WITHOUT_POSTGRES(db);
    name = db.name();
    EXPECT_TRUE(std::regex_match(name, std::regex("fesbench_t_" + std::to_string(::getpid()) +
                                                  R"(_\d+_\d+)")))
        << name;
    EXPECT_EQ(db.url(), base_url + name);
    EXPECT_EQ(PgTestDatabaseCount(base_url, name), 1);

    EXPECT_EQ(PgTestQuery(db.url(), "CREATE TABLE t (id integer PRIMARY KEY, label text)").error,
              "");
    EXPECT_EQ(PgTestQuery(db.url(), "INSERT INTO t VALUES (1, 'knee'), (2, 'ankle')").error, "");
    const PgTestRows rows = PgTestQuery(db.url(), "SELECT id, label FROM t ORDER BY id");
    ASSERT_EQ(rows.error, "");
    EXPECT_EQ(rows.rows, (std::vector<std::vector<std::string>>{{"1", "knee"}, {"2", "ankle"}}));
    // An open connection does not keep it from being dropped (WITH (FORCE)).
  }
  EXPECT_EQ(PgTestDatabaseCount(base_url, name), 0);
}

TEST(ScratchDatabaseTest, EachIsEmptyAndItsOwn) {
  ScratchDatabase a;
  FESBENCH_SKIP_WITHOUT_POSTGRES(a);
  ScratchDatabase b;
  FESBENCH_SKIP_WITHOUT_POSTGRES(b);
  EXPECT_NE(a.name(), b.name());
  ASSERT_EQ(PgTestQuery(a.url(), "CREATE TABLE only_in_a (x integer)").error, "");
  EXPECT_NE(PgTestQuery(b.url(), "SELECT * FROM only_in_a").error, "");
}

TEST(ScratchDatabaseTest, ManyThreadsAtOnce) {
  constexpr int kThreads = 4;
  std::vector<std::string> names(kThreads), errors(kThreads);
  std::vector<std::thread> threads;
  for (int i = 0; i < kThreads; ++i) {
    threads.emplace_back([&, i] {
      ScratchDatabase db;
      names[i] = db.name();
      errors[i] = db.skip_reason();
    });
  }
  for (std::thread& thread : threads) thread.join();
  if (SharedPostgresServer().binaries_missing) GTEST_SKIP() << SharedPostgresServer().skip_reason;
  for (int i = 0; i < kThreads; ++i) EXPECT_EQ(errors[i], "") << i;
  EXPECT_EQ(std::set<std::string>(names.begin(), names.end()).size(), size_t{kThreads});
}

TEST(PostgresServerTest, CreateAndDropDatabaseSayWhatWentWrong) {
  FESBENCH_SHARED_POSTGRES_OR_SKIP(shared);
  const std::string name = "fesbench_t_" + std::to_string(::getpid()) + "_direct";
  ASSERT_TRUE(CreateDatabase(shared.base_url, name).ok());
  const api::Status again = CreateDatabase(shared.base_url, name);
  EXPECT_EQ(again.code(), api::ErrorCode::kAlreadyExists) << again.ToString();
  EXPECT_NE(again.message().find("already exists"), std::string::npos) << again.ToString();
  EXPECT_TRUE(DropDatabase(shared.base_url, name).ok());
  EXPECT_TRUE(DropDatabase(shared.base_url, name).ok());  // IF EXISTS
  EXPECT_EQ(PgTestDatabaseCount(shared.base_url, name), 0);

  const api::Status unreachable = CreateDatabase("postgresql://postgres@127.0.0.1:1/", name);
  EXPECT_EQ(unreachable.code(), api::ErrorCode::kUnavailable) << unreachable.ToString();
}

TEST(PostgresServerTest, AnotherServerStartsAndStops) {
  FESBENCH_SHARED_POSTGRES_OR_SKIP(shared);
  const auto dir = std::filesystem::temp_directory_path() /
                   ("fesbench_pg_" + std::to_string(::getpid()) + "_other");
  auto started = PostgresServer::Start(dir);
  ASSERT_TRUE(started.ok()) << started.status().ToString();
  std::unique_ptr<PostgresServer> server = std::move(*started);
  EXPECT_NE(shared.base_url, server->Url(""));
  EXPECT_GT(server->port(), 0);
  EXPECT_EQ(server->Url("x"), "postgresql://postgres@127.0.0.1:" +
                                  std::to_string(server->port()) + "/x");
  EXPECT_EQ(PgTestQuery(server->Url("postgres"), "SELECT 1").error, "");
  EXPECT_TRUE(std::filesystem::exists(dir / "data" / "postmaster.pid"));

  const std::string url = server->Url("postgres");
  server.reset();
  EXPECT_FALSE(std::filesystem::exists(dir));
  EXPECT_NE(PgTestQuery(url, "SELECT 1").error, "");  // nobody listens any more
}

TEST(PostgresServerTest, BinDirHasTheServer) {
  const std::string bin = PostgresServer::BinDir();
  if (bin.empty()) GTEST_SKIP() << kBinariesMissing;
  EXPECT_TRUE(std::filesystem::exists(std::filesystem::path(bin) / "pg_ctl")) << bin;
  EXPECT_TRUE(std::filesystem::exists(std::filesystem::path(bin) / "postgres")) << bin;
}

}  // namespace
}  // namespace fesbench::testing
