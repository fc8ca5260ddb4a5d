#pragma once

/// @file
/// The embedded engine: one SQLite connection (storage/connection.h).

#include <memory>
#include <string>
#include <string_view>
#include <unordered_map>

#include "storage/connection.h"

struct sqlite3;
struct sqlite3_stmt;

namespace fesbench::storage {

class SqliteConnection final : public Connection {
 public:
  /// Opens `path` with the given sqlite3_open_v2 flags and applies the
  /// per-connection settings (busy timeout in ms, foreign keys on).
  static api::Result<std::unique_ptr<SqliteConnection>> Open(const std::string& path, int flags,
                                                             int busy_timeout_ms);
  ~SqliteConnection() override;

  Engine engine() const override { return Engine::kSqlite; }
  api::Result<Statement> Prepare(std::string_view sql) override;
  api::Status ExecScript(const std::string& sql) override;
  bool autocommit() const override;

  /// The status for SQLite result code `rc` (with `context` prefixed).
  api::Status StatusFromCode(int rc, std::string_view context);

  sqlite3* handle() const { return db_; }

 private:
  explicit SqliteConnection(sqlite3* db) : db_(db) {}
  sqlite3* db_;
  // Prepared statements by SQL text; a statement in use is not handed out
  // twice (a second Prepare of the same text gets an uncached one).
  std::unordered_map<std::string, std::unique_ptr<StatementImpl>> cache_;
};

}  // namespace fesbench::storage
