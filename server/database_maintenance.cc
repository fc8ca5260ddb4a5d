#include "server/database_maintenance.h"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <functional>
#include <ostream>
#include <string_view>
#include <vector>

#include "storage/database.h"
#include "storage/migrations.h"
#include "storage/postgres_connection.h"
#include "storage/private_files.h"

namespace fesbench::server {
namespace {

namespace fs = std::filesystem;

// "2026-11-27T20-41-07Z": a UTC time usable in a file name, in time order.
std::string FileStamp() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  ::gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H-%M-%SZ", &utc);
  return text;
}

// pg_dump of `url` into `destination` (custom format), through a temporary
// file made 0600 and renamed once pg_dump succeeded. The URL's password goes
// to pg_dump in its environment (PGPASSWORD: /proc/<pid>/environ is its
// user's and root's only), not on its command line, which `ps` shows every
// user; without one in the URL, pg_dump's environment is this process's
// (a PGPASSWORD or PGPASSFILE of the caller's applies).
api::Status DumpPostgres(const std::string& url, const fs::path& destination) {
  auto client = storage::SplitPassword(url);
  if (!client.ok()) return client.status();
  const fs::path temporary = destination.string() + ".partial-" + std::to_string(::getpid());
  if (auto made = storage::CreatePrivateFile(temporary); !made.ok()) return made;
  const std::string file_arg = "--file=" + temporary.string();
  const std::string db_arg = "--dbname=" + client->conninfo;
  std::vector<std::string> environment;
  for (char** variable = environ; *variable != nullptr; ++variable) {
    if (client->password.empty() || !std::string_view(*variable).starts_with("PGPASSWORD=")) {
      environment.emplace_back(*variable);
    }
  }
  if (!client->password.empty()) environment.push_back("PGPASSWORD=" + client->password);
  std::vector<char*> envp;
  for (std::string& variable : environment) envp.push_back(variable.data());
  envp.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    const char* argv[] = {"pg_dump", "--format=custom", file_arg.c_str(), db_arg.c_str(), nullptr};
    ::execvpe("pg_dump", const_cast<char* const*>(argv), envp.data());
    ::_exit(127);
  }
  int status = 0;
  if (pid < 0 || ::waitpid(pid, &status, 0) != pid) status = -1;
  std::error_code ec;
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    fs::remove(temporary, ec);
    const bool missing = WIFEXITED(status) && WEXITSTATUS(status) == 127;
    return api::Status::Unavailable(
        missing ? "pg_dump is not installed (Debian: postgresql-client)"
                : "pg_dump of " + storage::RedactedUrl(url) + " failed (its message above)");
  }
  fs::rename(temporary, destination, ec);
  if (ec) return api::Status::Unavailable("cannot move the dump to " + destination.string());
  return api::Status::Ok();
}

// Makes one backup named `name` in <data_dir>/backups; its path.
api::Result<fs::path> MakeBackup(const DatabaseLocation& location, const std::string& name) {
  const fs::path folder = location.data_dir / "backups";
  if (auto made = storage::CreatePrivateFolders(folder); !made.ok()) return made;
  const fs::path path = folder / (name + (location.postgres ? ".pgdump" : ".db"));
  api::Status status = location.postgres ? DumpPostgres(location.db, path)
                                         : storage::BackupSqliteFile(location.db, path.string());
  if (!status.ok()) return status;
  return path;
}

// A backup --migrate made before changing the database (a package upgrade):
// fesbench-<stamp>-schema-<N>.db or fesbench-<stamp>-before-migrate.pgdump.
bool IsPreMigrationBackup(const std::string& name) {
  return name.starts_with("fesbench-") &&
         ((name.ends_with(".db") && name.find("-schema-") != std::string::npos) ||
          name.ends_with("-before-migrate.pgdump"));
}

}  // namespace

int BackupDatabase(const DatabaseLocation& location, int keep_days, std::ostream& out,
                   std::ostream& err) {
  auto made = MakeBackup(location, "fesbench-" + FileStamp());
  if (!made.ok()) {
    err << "fesbench-server: backup failed: " << made.status().ToString() << std::endl;
    return 1;
  }
  std::error_code ec;
  out << "fesbench-server: backup " << made->string() << " (" << fs::file_size(*made, ec)
      << " bytes)" << std::endl;
  // Backups older than keep_days go, the one just made never. Pre-migration
  // backups are not counted by age: the newest kKeptPreMigrationBackups stay
  // whatever their age (the way back from an upgrade), older ones go.
  const auto cutoff = fs::file_time_type::clock::now() - std::chrono::hours(24) * keep_days;
  std::vector<fs::path> pre_migration;
  for (const auto& entry : fs::directory_iterator(made->parent_path(), ec)) {
    const std::string name = entry.path().filename().string();
    if (!entry.is_regular_file() || !name.starts_with("fesbench-") || entry.path() == *made) {
      continue;
    }
    if (IsPreMigrationBackup(name)) {
      pre_migration.push_back(entry.path());
      continue;
    }
    std::error_code time_ec;
    if (entry.last_write_time(time_ec) < cutoff && !time_ec && fs::remove(entry.path(), time_ec)) {
      out << "fesbench-server: deleted backup " << entry.path().string() << " (older than "
          << keep_days << " days)" << std::endl;
    }
  }
  // Newest first: the names begin with their UTC stamp.
  std::sort(pre_migration.begin(), pre_migration.end(), std::greater<>());
  for (std::size_t i = kKeptPreMigrationBackups; i < pre_migration.size(); ++i) {
    std::error_code remove_ec;
    if (fs::remove(pre_migration[i], remove_ec)) {
      out << "fesbench-server: deleted pre-migration backup " << pre_migration[i].string() << " ("
          << kKeptPreMigrationBackups << " newer ones kept)" << std::endl;
    }
  }
  return 0;
}

int MigrateDatabase(const DatabaseLocation& location, const std::string& bench_id,
                    std::ostream& out, std::ostream& err) {
  const int latest = storage::LatestSchemaVersion();
  const std::string shown = location.postgres ? storage::RedactedUrl(location.db) : location.db;
  if (!location.postgres) {
    auto version = storage::SqliteFileSchemaVersion(location.db);
    if (!version.ok() && version.status().code() == api::ErrorCode::kNotFound) {
      out << "fesbench-server: no database at " << shown
          << " yet; the first start creates it at schema version " << latest << std::endl;
      return 0;
    }
    if (!version.ok()) {
      err << "fesbench-server: cannot read " << shown << ": " << version.status().ToString()
          << std::endl;
      return 1;
    }
    if (*version > latest) {
      err << "fesbench-server: database " << shown << " has schema version " << *version
          << ", newer than this fesbench-server " << FESBENCH_VERSION << " knows (" << latest
          << "): refusing to downgrade; install the version that wrote it, or restore a backup "
             "made at schema version "
          << latest << " or older" << std::endl;
      return 1;
    }
    // Backed up also when nothing changes: the package runs this at every
    // upgrade, and a new version may write the same schema differently.
    auto backup = MakeBackup(location, "fesbench-" + FileStamp() + "-schema-" +
                                           std::to_string(*version));
    if (!backup.ok()) {
      err << "fesbench-server: backup before migrating failed, nothing migrated: "
          << backup.status().ToString() << std::endl;
      return 1;
    }
    out << "fesbench-server: backup of schema version " << *version << " in "
        << backup->string() << std::endl;
    if (*version == latest) {
      out << "fesbench-server: database " << shown << " is at schema version " << latest
          << "; nothing to migrate" << std::endl;
      return 0;
    }
  } else {
    auto backup = MakeBackup(location, "fesbench-" + FileStamp() + "-before-migrate");
    if (!backup.ok()) {
      err << "fesbench-server: backup before migrating failed, nothing migrated: "
          << backup.status().ToString() << std::endl;
      return 1;
    }
    out << "fesbench-server: dump in " << backup->string() << std::endl;
  }
  storage::DatabaseOptions options;
  options.path = location.db;
  options.bench_id = bench_id;
  auto db = storage::Database::Open(options);  // migrates; refuses a newer schema
  if (!db.ok()) {
    err << "fesbench-server: cannot migrate " << shown << ": " << db.status().ToString()
        << std::endl;
    return 1;
  }
  out << "fesbench-server: database " << shown << " is at schema version " << latest << std::endl;
  return 0;
}

}  // namespace fesbench::server
