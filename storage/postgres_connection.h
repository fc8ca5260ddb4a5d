#pragma once

/// @file
/// The server engine: one connection to PostgreSQL through libpq
/// (storage/connection.h). The repositories' `?N` parameters become `$N`;
/// statements are prepared on the server once per connection and run with
/// their values sent as text (BLOBs as binary bytea); rows come back as text
/// (integers and doubles parsed exactly: PostgreSQL 12+ prints the shortest
/// text that reads back to the same double).

#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <thread>
#include <unordered_map>
#include <vector>

#include "storage/connection.h"

struct pg_conn;
struct pg_result;

namespace fesbench::storage {

class PostgresConnection final : public Connection {
 public:
  /// Connects to `url` (postgresql://user[:password]@host[:port]/database[?…],
  /// libpq's URI form). kUnavailable naming the server when it cannot.
  static api::Result<std::unique_ptr<PostgresConnection>> Open(const std::string& url);
  ~PostgresConnection() override;

  Engine engine() const override { return Engine::kPostgres; }
  api::Result<Statement> Prepare(std::string_view sql) override;
  api::Status ExecScript(const std::string& sql) override;
  bool autocommit() const override;
  /// Reconnects when the server dropped the connection (a restart, a
  /// failover); the prepared statements are prepared again as needed.
  api::Status EnsureOpen() override;

  /// The status for a failed result (SQLSTATE mapped as in connection.h),
  /// with `context` prefixed; `result` may be null (connection lost).
  api::Status StatusFromResult(const pg_result* result, std::string_view context);

  pg_conn* handle() const { return conn_; }

 private:
  PostgresConnection(pg_conn* conn, std::string url) : conn_(conn), url_(std::move(url)) {}
  pg_conn* conn_;
  std::string url_;
  std::unordered_map<std::string, std::unique_ptr<StatementImpl>> cache_;
  int next_statement_ = 0;  // names the server-side prepared statements s0, s1, …
};

/// Receives the NOTIFY payloads of one channel on a connection and a thread
/// of its own until destroyed (reconnecting when the server drops it).
/// `on_payload` runs on that thread.
class PostgresListener {
 public:
  static api::Result<std::unique_ptr<PostgresListener>> Start(
      const std::string& url, const std::string& channel,
      std::function<void(std::string_view payload)> on_payload);
  ~PostgresListener();
  PostgresListener(const PostgresListener&) = delete;
  PostgresListener& operator=(const PostgresListener&) = delete;

 private:
  PostgresListener(std::string url, std::string channel,
                   std::function<void(std::string_view)> on_payload)
      : url_(std::move(url)), channel_(std::move(channel)), on_payload_(std::move(on_payload)) {}
  // Connects and LISTENs; null when the server cannot be reached.
  pg_conn* Connect() const;
  void Loop(pg_conn* conn);

  std::string url_;
  std::string channel_;
  std::function<void(std::string_view)> on_payload_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

/// `sql` with SQLite-style parameters (`?N`, or `?` numbered in order) as
/// PostgreSQL's `$N`, leaving quoted text and comments alone; `used[i]`
/// tells whether parameter i + 1 occurs (its size is the highest number).
/// A parameter whose type the server cannot infer (one only tested with IS
/// NULL) needs a CAST in the SQL, which SQLite reads the same way.
std::string PostgresParameters(std::string_view sql, std::vector<bool>& used);

/// A URL with its password hidden, for logs and messages.
std::string RedactedUrl(std::string_view url);

/// A URL split for a client program such as pg_dump: its settings as a
/// libpq connection string without the password (keyword='value' pairs, fit
/// for a command line, which every user sees in `ps`), and the password
/// apart, decoded ("" when the URL has none), for the program's PGPASSWORD.
struct ClientConnection {
  std::string conninfo;
  std::string password;
};
/// kInvalidArgument naming the URL without its password when libpq cannot
/// read it.
api::Result<ClientConnection> SplitPassword(const std::string& url);

}  // namespace fesbench::storage
