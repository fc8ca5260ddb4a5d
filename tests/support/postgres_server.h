#pragma once

// A real PostgreSQL server for tests and benchmarks: initdb into
// a temporary folder, started on a free loopback port, stopped at the end.
// initdb and postgres refuse to run as root; as root they run as the
// `postgres` system user (the Debian package creates it).
//
// Tests share one server per ctest run: the fixture test
// postgres_fixture_start (tests/support/CMakeLists.txt) starts it and writes
// its base URL to $FESBENCH_TEST_PG_DIR/url; a test binary run on its own
// starts one itself. Each test then takes a ScratchDatabase of its own.

#include <sys/types.h>

#include <filesystem>
#include <memory>
#include <string>
#include <string_view>

#include "api/status.h"

namespace fesbench::testing {

/// Why the PostgreSQL tests skip on a machine without the server.
inline constexpr std::string_view kBinariesMissing =
    "PostgreSQL server binaries not found (install postgresql-15: scripts/setup.sh does)";

class PostgresServer {
 public:
  /// initdb into `dir`/data (`dir` is emptied first) and start the server on
  /// a free loopback port, waiting until it accepts connections; kUnavailable
  /// (with initdb's output or the server log) when the binaries are missing
  /// or the server does not come up.
  static api::Result<std::unique_ptr<PostgresServer>> Start(const std::filesystem::path& dir);
  /// Stops the server (pg_ctl stop -m fast) and removes its folder, unless
  /// detached (or in a forked child of the process that started it).
  ~PostgresServer();
  PostgresServer(const PostgresServer&) = delete;
  PostgresServer& operator=(const PostgresServer&) = delete;

  /// postgresql://postgres@127.0.0.1:<port>/<database>
  std::string Url(const std::string& database) const;
  int port() const { return port_; }
  /// Leaves the server running when this object goes (the ctest fixture).
  void Detach() { detached_ = true; }

  /// The folder of initdb/pg_ctl: $FESBENCH_PG_BIN, the newest
  /// /usr/lib/postgresql/<version>/bin, or `pg_config --bindir`; "" if none.
  static std::string BinDir();
  /// Stops a server started in `dir` (by another process) and removes it.
  static void StopIn(const std::filesystem::path& dir);

 private:
  PostgresServer(std::filesystem::path dir, int port);
  std::filesystem::path dir_;
  int port_;
  pid_t owner_pid_;
  bool detached_ = false;
};

/// CREATE DATABASE / DROP DATABASE IF EXISTS … WITH (FORCE) through the
/// server's `postgres` database; `base_url` ends with '/'. kUnavailable when
/// the server cannot be reached, kAlreadyExists for a taken name.
api::Status CreateDatabase(const std::string& base_url, const std::string& name);
api::Status DropDatabase(const std::string& base_url, const std::string& name);

/// The server this process's tests use: its base URL
/// ("postgresql://postgres@127.0.0.1:<port>/"), or why there is none. The
/// fixture's (the url file in $FESBENCH_TEST_PG_DIR) if there is one, else
/// one started on first use in <temp>/fesbench_pg_<pid> and stopped at exit
/// (then too any <temp>/fesbench_pg_<pid>[_…] of a process that died
/// without stopping its own). Thread-safe.
struct SharedPostgres {
  std::string base_url;
  std::string skip_reason;
  bool binaries_missing = false;  ///< the one reason a test may skip rather than fail
};
const SharedPostgres& SharedPostgresServer();

/// A fresh, empty database on the shared server for one test; dropped when
/// this goes.
class ScratchDatabase {
 public:
  ScratchDatabase();
  ~ScratchDatabase();
  ScratchDatabase(const ScratchDatabase&) = delete;
  ScratchDatabase& operator=(const ScratchDatabase&) = delete;

  bool ok() const { return skip_reason_.empty(); }
  /// Why there is no database (no server binaries, or creation failed).
  const std::string& skip_reason() const { return skip_reason_; }
  /// True when the reason is only that PostgreSQL is not installed here:
  /// the test is skipped (visibly); any other failure fails it.
  bool skippable() const { return binaries_missing_; }
  /// postgresql://postgres@127.0.0.1:<port>/<name>
  const std::string& url() const { return url_; }
  /// fesbench_t_<pid>_<counter>_<random>
  const std::string& name() const { return name_; }

 private:
  std::string base_url_;
  std::string name_;
  std::string url_;
  std::string skip_reason_;
  bool binaries_missing_ = false;
};

}  // namespace fesbench::testing
