#pragma once

/// @file
/// fesbench-server's maintenance steps on its database, each run by itself
/// and then exiting (server/config.h, ServerTask): the online backup that
/// fesbench-backup.service runs on a timer, and the migration with a backup
/// first that the Debian package's maintainer scripts run on an upgrade
/// (README, "Install on a lab PC"; docs/ARCHITECTURE.md, "Backup").

#include <cstddef>
#include <filesystem>
#include <iosfwd>
#include <string>

namespace fesbench::server {

/// The database a server is configured with.
struct DatabaseLocation {
  std::string db;  ///< the SQLite file (absolute) or the PostgreSQL URL
  bool postgres = false;
  std::filesystem::path data_dir;  ///< backups go to data_dir/backups (0700)
};

/// How many pre-migration backups (MigrateDatabase's) --backup keeps.
inline constexpr std::size_t kKeptPreMigrationBackups = 5;

/// An online backup into `<data_dir>/backups/fesbench-<UTC stamp>.db`
/// (SQLite, through storage::BackupSqliteFile: also while a server runs on
/// the file) or `.pgdump` (PostgreSQL: `pg_dump --format=custom`, the URL's
/// password in pg_dump's environment, not on its command line), then
/// deletes the `fesbench-*` backups there older than `keep_days`, except the
/// pre-migration backups: of those the newest kKeptPreMigrationBackups stay
/// whatever their age and older ones go. Prints what it made and deleted;
/// the exit code (0 done, 1 failed).
int BackupDatabase(const DatabaseLocation& location, int keep_days, std::ostream& out,
                   std::ostream& err);

/// Brings a stopped server's database to this software's schema, backing it
/// up first (the Debian package runs it at every install over an existing
/// database: the backup is the database as the previous version left it). A
/// database with a newer schema than this software knows (a downgrade) is
/// refused, exit 1, naming both versions, and left as it is. An SQLite file
/// is backed up as `fesbench-<stamp>-schema-<N>.db` (N its schema version),
/// then migrated if N is older; a missing file is left for the first start.
/// A PostgreSQL database is dumped first (`fesbench-<stamp>-before-migrate.pgdump`),
/// then migrated (the database refuses a newer schema itself).
int MigrateDatabase(const DatabaseLocation& location, const std::string& bench_id,
                    std::ostream& out, std::ostream& err);

}  // namespace fesbench::server
