#pragma once

/// @file
/// A thin RAII layer over one SQLite connection. Every statement that carries
/// a value is a prepared statement with bound parameters (cached per
/// connection by SQL text); only fixed SQL (pragmas, BEGIN/COMMIT, the
/// compiled-in migrations) is run as a script. SQLite result codes become
/// api::Status values here, in one place:
///   SQLITE_BUSY/LOCKED            → kUnavailable (and the connection notes it,
///                                   so Database can retry the transaction)
///   UNIQUE/PRIMARY KEY constraint → kAlreadyExists
///   CHECK/NOT NULL/FOREIGN KEY    → kInvalidArgument
///   trigger RAISE (append-only)   → kFailedPrecondition
///   CORRUPT/NOTADB                → kDataLoss
///   I/O, full disk, cannot open   → kUnavailable
///   anything else                 → kInternal

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "api/status.h"

struct sqlite3;
struct sqlite3_stmt;

namespace fesbench::storage {

class Connection;

/// A prepared statement in use. Reset and unbound when destroyed, so a cached
/// statement can be reused. Bind indexes start at 1, column indexes at 0.
class Statement {
 public:
  Statement(sqlite3_stmt* stmt, Connection* connection, bool owned);
  Statement(Statement&& other) noexcept;
  Statement& operator=(Statement&&) = delete;
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  ~Statement();

  Statement& Bind(int index, std::int64_t value);
  Statement& Bind(int index, int value) { return Bind(index, static_cast<std::int64_t>(value)); }
  Statement& Bind(int index, double value);
  Statement& Bind(int index, std::string_view text);
  Statement& Bind(int index, const std::string& text) {
    return Bind(index, std::string_view(text));
  }
  Statement& Bind(int index, const char* text) { return Bind(index, std::string_view(text)); }
  Statement& BindBlob(int index, std::span<const std::byte> blob);
  Statement& BindNull(int index);
  template <typename T>
  Statement& Bind(int index, const std::optional<T>& value) {
    return value ? Bind(index, *value) : BindNull(index);
  }

  /// Advances: true when a row is available, false when done.
  api::Result<bool> Step();
  /// Steps to completion, ignoring rows.
  api::Status Run();

  bool IsNull(int column) const;
  std::int64_t Int64(int column) const;
  double Double(int column) const;
  std::string Text(int column) const;
  std::optional<std::int64_t> OptionalInt64(int column) const;
  std::optional<double> OptionalDouble(int column) const;
  std::span<const std::byte> Blob(int column) const;

 private:
  sqlite3_stmt* stmt_;
  Connection* connection_;
  bool owned_;
  int bind_error_ = 0;  // first SQLite error from a Bind call, reported by Step
};

/// One SQLite connection with a cache of prepared statements. Not thread
/// safe: Database hands each connection to one thread at a time.
class Connection {
 public:
  /// Opens `path` with the given sqlite3_open_v2 flags and applies the
  /// per-connection settings (busy timeout in ms, foreign keys on).
  static api::Result<std::unique_ptr<Connection>> Open(const std::string& path, int flags,
                                                       int busy_timeout_ms);
  ~Connection();
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  /// A prepared statement for `sql`, from the cache when it is free.
  api::Result<Statement> Prepare(std::string_view sql);
  /// Runs fixed SQL (no values from callers). May hold several statements.
  api::Status ExecScript(const std::string& sql);
  /// The single text value of a one-row pragma or query without parameters.
  api::Result<std::string> QueryText(const std::string& sql);

  /// The rowid of the last INSERT on this connection.
  std::int64_t LastInsertRowId() const;
  /// True when a statement met SQLITE_BUSY/LOCKED since ClearBusy().
  bool busy_seen() const { return busy_seen_; }
  void ClearBusy() { busy_seen_ = false; }
  /// True when no transaction is open.
  bool autocommit() const;

  /// The status for SQLite result code `rc` (with `context` prefixed).
  api::Status StatusFromCode(int rc, std::string_view context);

  sqlite3* handle() const { return db_; }

 private:
  explicit Connection(sqlite3* db) : db_(db) {}
  friend class Statement;
  void Release(sqlite3_stmt* stmt);

  struct CacheEntry {
    sqlite3_stmt* stmt = nullptr;
    bool in_use = false;
  };
  sqlite3* db_;
  std::unordered_map<std::string, CacheEntry> cache_;
  bool busy_seen_ = false;
};

/// Packs samples as little-endian IEEE-754 float64, 8 bytes each.
std::vector<std::byte> PackFloat64Le(std::span<const double> samples);
/// Inverse of PackFloat64Le; nullopt when the size is not a multiple of 8.
std::optional<std::vector<double>> UnpackFloat64Le(std::span<const std::byte> blob);

}  // namespace fesbench::storage
