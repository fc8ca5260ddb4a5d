// fesbench-server --migrate and --backup (server/database_maintenance.h), as
// the Debian package's postinst and backup timer run them: an older database
// is backed up before it is migrated, a newer one is refused naming both
// schema versions and left as it is, and a backup made while a server holds
// the file is a consistent copy, 0600, with older backups deleted.

#include "server/database_maintenance.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "storage/database.h"
#include "storage/migrations.h"
#include "tests/support/postgres_gtest.h"

#ifndef FESBENCH_SERVER_BINARY
#error "FESBENCH_SERVER_BINARY must name the fesbench-server executable"
#endif

namespace {

namespace fs = std::filesystem;
using fesbench::storage::Database;
using fesbench::storage::DatabaseOptions;
using fesbench::storage::LatestSchemaVersion;
using fesbench::storage::SqliteFileSchemaVersion;

struct ServerRun {
  int exit_code = -1;
  std::string output;
};

// fesbench-server with `args`, its stdout and stderr together.
ServerRun RunServer(const std::vector<std::string>& args) {
  int fds[2];
  if (::pipe(fds) != 0) return {};
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::dup2(fds[1], STDOUT_FILENO);
    ::dup2(fds[1], STDERR_FILENO);
    ::close(fds[0]);
    std::vector<char*> argv = {const_cast<char*>(FESBENCH_SERVER_BINARY)};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  ::close(fds[1]);
  ServerRun run;
  char buffer[4096];
  for (ssize_t n; (n = ::read(fds[0], buffer, sizeof buffer)) > 0;) run.output.append(buffer, n);
  ::close(fds[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return run;
}

// The files in `folder` but the -wal and -shm files SQLite makes beside a
// backup the test opened.
std::vector<fs::path> Backups(const fs::path& folder) {
  std::vector<fs::path> found;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    const std::string name = entry.path().filename().string();
    if (!name.ends_with("-wal") && !name.ends_with("-shm")) found.push_back(entry.path());
  }
  return found;
}

class DatabaseMaintenanceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char pattern[] = "/tmp/fesbench-maintenance-XXXXXX";
    ASSERT_NE(::mkdtemp(pattern), nullptr);
    dir_ = pattern;
    db_ = (dir_ / "fesbench.db").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  // A database made by an older fesbench: migrated up to `version` only.
  void MakeDatabaseAt(int version) {
    DatabaseOptions options;
    options.path = db_;
    options.target_schema_version = version;
    auto db = Database::Open(options);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
  }

  fs::path dir_;
  std::string db_;
};

TEST_F(DatabaseMaintenanceTest, AnOlderDatabaseIsBackedUpThenMigrated) {
  const int older = LatestSchemaVersion() - 3;
  MakeDatabaseAt(older);
  const ServerRun run = RunServer({"--db", db_, "--migrate"});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_EQ(*SqliteFileSchemaVersion(db_), LatestSchemaVersion());
  const std::vector<fs::path> backups = Backups(dir_ / "backups");
  ASSERT_EQ(backups.size(), 1u) << run.output;
  const std::string name = backups[0].filename().string();
  EXPECT_TRUE(name.starts_with("fesbench-") && name.ends_with("-schema-" + std::to_string(older) + ".db"))
      << name;
  // The backup is the database as it was, before the migration.
  EXPECT_EQ(*SqliteFileSchemaVersion(backups[0].string()), older);
  EXPECT_NE(run.output.find("backup of schema version " + std::to_string(older)), std::string::npos)
      << run.output;
  struct stat info {};
  ASSERT_EQ(::stat(backups[0].c_str(), &info), 0);
  EXPECT_EQ(info.st_mode & 0777, 0600u);

  // Again (a reinstall): nothing to migrate, but the database is backed up
  // as it is first.
  const ServerRun again = RunServer({"--db", db_, "--migrate"});
  EXPECT_EQ(again.exit_code, 0) << again.output;
  EXPECT_NE(again.output.find("nothing to migrate"), std::string::npos) << again.output;
  const std::string latest = std::to_string(LatestSchemaVersion());
  EXPECT_NE(again.output.find("backup of schema version " + latest), std::string::npos)
      << again.output;
  const std::vector<fs::path> after = Backups(dir_ / "backups");
  ASSERT_EQ(after.size(), 2u) << again.output;
  for (const fs::path& p : after) {
    if (p == backups[0]) continue;
    EXPECT_TRUE(p.filename().string().ends_with("-schema-" + latest + ".db")) << p;
    EXPECT_EQ(*SqliteFileSchemaVersion(p.string()), LatestSchemaVersion());
  }
}

TEST_F(DatabaseMaintenanceTest, ANewerDatabaseIsRefusedNamingBothSchemaVersions) {
  MakeDatabaseAt(LatestSchemaVersion());
  {
    DatabaseOptions options;
    options.path = db_;
    auto db = Database::Open(options);
    ASSERT_TRUE(db.ok());
    ASSERT_TRUE((*db)
                    ->Write([&](fesbench::storage::Connection& c) {
                      return c.ExecScript("PRAGMA user_version = " +
                                          std::to_string(LatestSchemaVersion() + 2));
                    })
                    .ok());
  }
  const int newer = LatestSchemaVersion() + 2;
  const ServerRun run = RunServer({"--db", db_, "--migrate"});
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_NE(run.output.find("schema version " + std::to_string(newer) + ", newer than this "
                            "fesbench-server"),
            std::string::npos)
      << run.output;
  EXPECT_NE(run.output.find("knows (" + std::to_string(LatestSchemaVersion()) + ")"),
            std::string::npos)
      << run.output;
  EXPECT_EQ(*SqliteFileSchemaVersion(db_), newer);  // untouched
  EXPECT_TRUE(Backups(dir_ / "backups").empty());
}

TEST_F(DatabaseMaintenanceTest, NoDatabaseYetIsLeftForTheFirstStart) {
  const ServerRun run = RunServer({"--db", db_, "--migrate"});
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("no database at"), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(db_));
}

TEST_F(DatabaseMaintenanceTest, BackupWhileTheFileIsHeldAndOldBackupsDeleted) {
  DatabaseOptions options;
  options.path = db_;
  auto held = Database::Open(options);  // holds <db>.lock, as a running server does
  ASSERT_TRUE(held.ok());
  fs::create_directories(dir_ / "backups");
  const fs::path old_backup = dir_ / "backups" / "fesbench-2020-01-01T00-00-00Z.db";
  const fs::path other_file = dir_ / "backups" / "notes.txt";
  for (const fs::path& p : {old_backup, other_file}) {
    fs::copy_file(db_, p);
    fs::last_write_time(p, fs::file_time_type::clock::now() - std::chrono::hours(24 * 20));
  }
  const ServerRun run = RunServer({"--db", db_, "--backup", "--backup-keep-days", "14"});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_FALSE(fs::exists(old_backup)) << run.output;
  EXPECT_TRUE(fs::exists(other_file));  // not one of ours
  const std::vector<fs::path> backups = Backups(dir_ / "backups");
  ASSERT_EQ(backups.size(), 2u);
  for (const fs::path& p : backups) {
    if (p == other_file) continue;
    EXPECT_EQ(*SqliteFileSchemaVersion(p.string()), LatestSchemaVersion());
    struct stat info {};
    ASSERT_EQ(::stat(p.c_str(), &info), 0);
    EXPECT_EQ(info.st_mode & 0777, 0600u);
  }
  // A server on the file is not disturbed: it still writes.
  EXPECT_TRUE((*held)->CheckIntegrity().ok());
}

// The backups --migrate made before an upgrade are the way back from it: the
// age pruning leaves them, and only those beyond the newest
// kKeptPreMigrationBackups go.
TEST_F(DatabaseMaintenanceTest, PreMigrationBackupsAreKeptOutOfTheAgePruning) {
  MakeDatabaseAt(LatestSchemaVersion());
  const fs::path folder = dir_ / "backups";
  fs::create_directories(folder);
  const fs::path old_daily = folder / "fesbench-2020-01-01T00-00-00Z.db";
  std::vector<fs::path> pre_migration;  // oldest first
  for (int day = 1; day <= 6; ++day) {
    const std::string stamp = "fesbench-2020-02-0" + std::to_string(day) + "T00-00-00Z";
    pre_migration.push_back(folder /
                            (stamp + (day == 4 ? "-before-migrate.pgdump"
                                               : "-schema-" + std::to_string(day + 10) + ".db")));
  }
  ASSERT_EQ(fesbench::server::kKeptPreMigrationBackups, pre_migration.size() - 1);
  for (const fs::path& p : pre_migration) fs::copy_file(db_, p);
  fs::copy_file(db_, old_daily);
  for (const fs::path& p : fs::directory_iterator(folder)) {
    fs::last_write_time(p, fs::file_time_type::clock::now() - std::chrono::hours(24 * 400));
  }

  const ServerRun run = RunServer({"--db", db_, "--backup", "--backup-keep-days", "14"});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_FALSE(fs::exists(old_daily)) << run.output;
  EXPECT_FALSE(fs::exists(pre_migration[0])) << run.output;  // beyond the newest five
  EXPECT_NE(run.output.find("deleted pre-migration backup " + pre_migration[0].string()),
            std::string::npos)
      << run.output;
  for (std::size_t i = 1; i < pre_migration.size(); ++i) {
    EXPECT_TRUE(fs::exists(pre_migration[i])) << pre_migration[i] << "\n" << run.output;
  }
  EXPECT_EQ(Backups(folder).size(), pre_migration.size());  // five kept and today's
}

// pg_dump is given the URL's password in its environment, not on its command
// line (which `ps` shows every user): a pg_dump of the test's own, first on
// PATH, records what it got and writes the dump.
TEST_F(DatabaseMaintenanceTest, PgDumpGetsThePasswordInItsEnvironmentNotItsArguments) {
  const fs::path bin = dir_ / "bin";
  fs::create_directories(bin);
  {
    std::ofstream script(bin / "pg_dump");
    script << "#!/bin/sh\n"
              "printf '%s\\n' \"$@\" > \"$(dirname \"$0\")/arguments\"\n"
              "printf '%s' \"${PGPASSWORD-unset}\" > \"$(dirname \"$0\")/password\"\n"
              "for a; do case $a in --file=*) echo dump > \"${a#--file=}\" ;; esac; done\n";
  }
  fs::permissions(bin / "pg_dump", fs::perms::owner_all);
  const std::string path = std::getenv("PATH") != nullptr ? std::getenv("PATH") : "/usr/bin:/bin";
  ::setenv("PATH", (bin.string() + ":" + path).c_str(), 1);
  const ServerRun run =
      RunServer({"--db", "postgresql://lab:s3cr%27t%40x@127.0.0.1:5433/fesbench?sslmode=disable",
                 "--data-dir", dir_.string(), "--backup"});
  ::setenv("PATH", path.c_str(), 1);
  ASSERT_EQ(run.exit_code, 0) << run.output;

  std::ifstream arguments_file(bin / "arguments");
  const std::string arguments((std::istreambuf_iterator<char>(arguments_file)),
                              std::istreambuf_iterator<char>());
  EXPECT_EQ(arguments.find("s3cr"), std::string::npos) << arguments;
  EXPECT_NE(arguments.find("--dbname="), std::string::npos) << arguments;
  for (const char* setting : {"user='lab'", "host='127.0.0.1'", "port='5433'", "dbname='fesbench'",
                              "sslmode='disable'"}) {
    EXPECT_NE(arguments.find(setting), std::string::npos) << setting << " in " << arguments;
  }
  std::ifstream password_file(bin / "password");
  const std::string password((std::istreambuf_iterator<char>(password_file)),
                             std::istreambuf_iterator<char>());
  EXPECT_EQ(password, "s3cr't@x");  // decoded from the URL
  const std::vector<fs::path> dumps = Backups(dir_ / "backups");
  ASSERT_EQ(dumps.size(), 1u) << run.output;
  EXPECT_TRUE(dumps[0].filename().string().ends_with(".pgdump")) << dumps[0];
  struct stat info {};
  ASSERT_EQ(::stat(dumps[0].c_str(), &info), 0);
  EXPECT_EQ(info.st_mode & 0777, 0600u);
  EXPECT_EQ(run.output.find("s3cr"), std::string::npos) << run.output;
}

// The real pg_dump on a PostgreSQL database, the URL with a password (the
// test server trusts loopback, so only the split is exercised): --migrate
// dumps before it migrates, --backup dumps, and pg_restore reads both.
TEST_F(DatabaseMaintenanceTest, PostgresIsDumpedBeforeMigratingAndBackedUpWithPgDump) {
  fesbench::testing::ScratchDatabase database;
  FESBENCH_SKIP_WITHOUT_POSTGRES(database);
  std::string url = database.url();  // postgresql://postgres@…
  url.insert(url.find('@'), ":not-on-the-command-line");
  const ServerRun migrated = RunServer({"--db", url, "--data-dir", dir_.string(), "--migrate"});
  ASSERT_EQ(migrated.exit_code, 0) << migrated.output;
  const ServerRun backed_up = RunServer({"--db", url, "--data-dir", dir_.string(), "--backup"});
  ASSERT_EQ(backed_up.exit_code, 0) << backed_up.output;
  EXPECT_EQ(backed_up.output.find("not-on-the-command-line"), std::string::npos)
      << backed_up.output;
  const std::vector<fs::path> dumps = Backups(dir_ / "backups");
  ASSERT_EQ(dumps.size(), 2u) << migrated.output << backed_up.output;
  for (const fs::path& dump : dumps) {
    EXPECT_TRUE(dump.filename().string().ends_with(".pgdump")) << dump;
    const std::string list = "pg_restore --list '" + dump.string() + "' > /dev/null";
    EXPECT_EQ(std::system(list.c_str()), 0) << dump;
  }
}

}  // namespace
