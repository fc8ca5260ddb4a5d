#pragma once

/// @file
/// One database connection, whichever engine is behind it (docs/ARCHITECTURE.md, storage):
/// the repositories write their SQL once, with `?1, ?2, …` parameters, and
/// read rows through Statement. Two engines implement it:
///   storage/sqlite_connection.h    the embedded file (the default);
///   storage/postgres_connection.h  a PostgreSQL server (libpq).
/// Every statement that carries a value is a prepared statement with bound
/// parameters (cached per connection by SQL text); only fixed SQL (BEGIN,
/// COMMIT, the compiled-in migrations) runs as a script. Each engine maps
/// its errors to api::Status in one place, the same way:
///   contention (SQLite busy/locked, PostgreSQL serialization failure or
///   deadlock)                       → kUnavailable, and busy_seen() is set
///                                     so Database retries the transaction
///   unique or primary key            → kAlreadyExists
///   check, not null, foreign key     → kInvalidArgument
///   append-only trigger              → kFailedPrecondition
///   corrupt file or data             → kDataLoss
///   I/O, full disk, cannot connect   → kUnavailable
///   anything else                    → kInternal

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "api/status.h"

namespace fesbench::storage {

/// Which engine stores the data.
enum class Engine { kSqlite, kPostgres };

/// The engine side of a prepared statement (internal to storage/).
class StatementImpl {
 public:
  virtual ~StatementImpl() = default;
  virtual void BindInt64(int index, std::int64_t value) = 0;
  virtual void BindDouble(int index, double value) = 0;
  virtual void BindText(int index, std::string_view text) = 0;
  virtual void BindBlob(int index, std::span<const std::byte> blob) = 0;
  virtual void BindNull(int index) = 0;
  virtual api::Result<bool> Step() = 0;
  virtual bool IsNull(int column) const = 0;
  virtual std::int64_t Int64(int column) const = 0;
  virtual double Double(int column) const = 0;
  virtual std::string Text(int column) const = 0;
  virtual std::span<const std::byte> Blob(int column) const = 0;
  /// Back to its prepared state, bindings cleared: the statement is free for
  /// the connection's cache again (a cached statement is never deleted here).
  virtual void Release() = 0;

  bool in_use = false;  ///< handed out by the connection's cache
};

/// A prepared statement in use. Reset and unbound when destroyed, so a cached
/// statement can be reused. Bind indexes start at 1, column indexes at 0.
class Statement {
 public:
  /// `impl` is the connection's cached statement (released when this one is
  /// destroyed), or, with `owned`, one this statement deletes.
  Statement(StatementImpl* impl, bool owned) : impl_(impl), owned_(owned) {}
  Statement(Statement&& other) noexcept;
  Statement& operator=(Statement&&) = delete;
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  ~Statement();

  Statement& Bind(int index, std::int64_t value) {
    impl_->BindInt64(index, value);
    return *this;
  }
  Statement& Bind(int index, int value) { return Bind(index, static_cast<std::int64_t>(value)); }
  Statement& Bind(int index, double value) {
    impl_->BindDouble(index, value);
    return *this;
  }
  Statement& Bind(int index, std::string_view text) {
    impl_->BindText(index, text);
    return *this;
  }
  Statement& Bind(int index, const std::string& text) {
    return Bind(index, std::string_view(text));
  }
  Statement& Bind(int index, const char* text) { return Bind(index, std::string_view(text)); }
  Statement& BindBlob(int index, std::span<const std::byte> blob) {
    impl_->BindBlob(index, blob);
    return *this;
  }
  Statement& BindNull(int index) {
    impl_->BindNull(index);
    return *this;
  }
  template <typename T>
  Statement& Bind(int index, const std::optional<T>& value) {
    return value ? Bind(index, *value) : BindNull(index);
  }

  /// Advances: true when a row is available, false when done.
  api::Result<bool> Step() { return impl_->Step(); }
  /// Steps to completion, ignoring rows.
  api::Status Run();

  bool IsNull(int column) const { return impl_->IsNull(column); }
  std::int64_t Int64(int column) const { return impl_->Int64(column); }
  double Double(int column) const { return impl_->Double(column); }
  std::string Text(int column) const { return impl_->Text(column); }
  std::optional<std::int64_t> OptionalInt64(int column) const;
  std::optional<double> OptionalDouble(int column) const;
  /// Valid until the next Step.
  std::span<const std::byte> Blob(int column) const { return impl_->Blob(column); }

 private:
  StatementImpl* impl_;
  bool owned_;
};

/// One connection with a cache of prepared statements. Not thread safe:
/// Database hands each connection to one thread at a time.
class Connection {
 public:
  virtual ~Connection() = default;
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  virtual Engine engine() const = 0;
  /// A prepared statement for `sql` (parameters `?1, ?2, …`), from the cache
  /// when it is free.
  virtual api::Result<Statement> Prepare(std::string_view sql) = 0;
  /// Runs fixed SQL (no values from callers). May hold several statements.
  virtual api::Status ExecScript(const std::string& sql) = 0;
  /// True when no transaction is open.
  virtual bool autocommit() const = 0;
  /// Reconnects a connection the server dropped (PostgreSQL); OK when the
  /// connection is usable.
  virtual api::Status EnsureOpen() { return api::Status::Ok(); }

  /// The single text value of the first row of a query without parameters
  /// ("" when it returns no row).
  api::Result<std::string> QueryText(const std::string& sql);

  /// True when a statement met contention since ClearBusy().
  bool busy_seen() const { return busy_seen_; }
  /// True when a statement hit a unique key since ClearBusy() on an engine
  /// where that may be the loser's side of a race between two servers
  /// (PostgreSQL can report it so instead of a serialization failure).
  bool unique_conflict_seen() const { return unique_conflict_seen_; }
  void ClearBusy() { busy_seen_ = unique_conflict_seen_ = false; }

 protected:
  Connection() = default;
  void NoteBusy() { busy_seen_ = true; }
  void NoteUniqueConflict() { unique_conflict_seen_ = true; }

 private:
  bool busy_seen_ = false;
  bool unique_conflict_seen_ = false;
};

/// Packs samples as little-endian IEEE-754 float64, 8 bytes each.
std::vector<std::byte> PackFloat64Le(std::span<const double> samples);
/// Inverse of PackFloat64Le; nullopt when the size is not a multiple of 8.
std::optional<std::vector<double>> UnpackFloat64Le(std::span<const std::byte> blob);

}  // namespace fesbench::storage
