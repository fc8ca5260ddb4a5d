#include "storage/postgres_connection.h"

#include <libpq-fe.h>
#include <poll.h>

#include <cctype>
#include <charconv>
#include <cstring>
#include <limits>
#include <vector>

namespace fesbench::storage {
namespace {

int HexDigit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// bytea in its text output form ("\x" and two hex digits per byte, the
// default bytea_output); empty when the text is not in that form.
std::vector<std::byte> DecodeByteaHex(const char* text, int length) {
  std::vector<std::byte> bytes;
  if (length < 2 || text[0] != '\\' || text[1] != 'x' || (length - 2) % 2 != 0) return bytes;
  bytes.resize(static_cast<std::size_t>(length - 2) / 2);
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    const int hi = HexDigit(text[2 + 2 * i]);
    const int lo = HexDigit(text[3 + 2 * i]);
    if (hi < 0 || lo < 0) return {};
    bytes[i] = static_cast<std::byte>(hi * 16 + lo);
  }
  return bytes;
}

void IgnoreNotice(void*, const char*) {}

}  // namespace

// The values of one execution, then its rows. Prepared on the server under
// `name` (cached statements), or sent with its text each time (a second use
// of a statement whose cached copy is busy).
class PostgresStatement final : public StatementImpl {
 public:
  PostgresStatement(PostgresConnection* connection, std::string name, std::string sql,
                    std::vector<Oid> types)
      : connection_(connection),
        name_(std::move(name)),
        sql_(std::move(sql)),
        types_(std::move(types)),
        values_(types_.size()),
        null_(types_.size(), true),
        binary_(types_.size(), 0) {}
  ~PostgresStatement() override { PQclear(result_); }

  void BindInt64(int index, std::int64_t value) override { Set(index, std::to_string(value), 0); }
  void BindDouble(int index, double value) override {
    char buffer[32];
    const auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, value);
    Set(index, std::string(buffer, ec == std::errc() ? end : buffer), 0);
  }
  void BindText(int index, std::string_view text) override { Set(index, std::string(text), 0); }
  void BindBlob(int index, std::span<const std::byte> blob) override {
    Set(index, std::string(reinterpret_cast<const char*>(blob.data()), blob.size()), 1);
  }
  void BindNull(int index) override {
    if (!InRange(index)) return;
    null_[static_cast<std::size_t>(index - 1)] = true;
  }

  api::Result<bool> Step() override {
    if (bad_index_ != 0) {
      return api::Status::Internal("binding parameter " + std::to_string(bad_index_) +
                                   " of a statement with " + std::to_string(values_.size()));
    }
    if (!executed_) {
      executed_ = true;
      if (auto status = Execute(); !status.ok()) return status;
      row_ = -1;
    }
    if (result_ == nullptr) return false;
    ++row_;
    return row_ < PQntuples(result_);
  }

  bool IsNull(int column) const override { return PQgetisnull(result_, row_, column) != 0; }
  std::int64_t Int64(int column) const override {
    const char* text = PQgetvalue(result_, row_, column);
    const int length = PQgetlength(result_, row_, column);
    if (length == 1 && (text[0] == 't' || text[0] == 'f')) return text[0] == 't' ? 1 : 0;
    std::int64_t value = 0;
    const auto [end, ec] = std::from_chars(text, text + length, value);
    if (ec == std::errc() && end == text + length) return value;
    return static_cast<std::int64_t>(Double(column));  // numeric, e.g. an average
  }
  double Double(int column) const override {
    const char* text = PQgetvalue(result_, row_, column);
    const int length = PQgetlength(result_, row_, column);
    double value = 0.0;
    const auto [end, ec] = std::from_chars(text, text + length, value);
    if (ec == std::errc()) return value;
    if (std::strcmp(text, "Infinity") == 0) return std::numeric_limits<double>::infinity();
    if (std::strcmp(text, "-Infinity") == 0) return -std::numeric_limits<double>::infinity();
    return std::numeric_limits<double>::quiet_NaN();
  }
  std::string Text(int column) const override {
    return std::string(PQgetvalue(result_, row_, column),
                       static_cast<std::size_t>(PQgetlength(result_, row_, column)));
  }
  std::span<const std::byte> Blob(int column) const override {
    if (IsNull(column)) return {};
    blobs_.push_back(
        DecodeByteaHex(PQgetvalue(result_, row_, column), PQgetlength(result_, row_, column)));
    return blobs_.back();
  }

  void Release() override {
    PQclear(result_);
    result_ = nullptr;
    executed_ = false;
    bad_index_ = 0;
    blobs_.clear();
    std::fill(null_.begin(), null_.end(), true);
    std::fill(binary_.begin(), binary_.end(), 0);
    in_use = false;
  }

 private:
  bool InRange(int index) {
    if (index >= 1 && static_cast<std::size_t>(index) <= values_.size()) return true;
    if (bad_index_ == 0) bad_index_ = index;
    return false;
  }
  void Set(int index, std::string value, int binary) {
    if (!InRange(index)) return;
    const auto i = static_cast<std::size_t>(index - 1);
    values_[i] = std::move(value);
    null_[i] = false;
    binary_[i] = binary;
  }

  api::Status Execute() {
    const std::size_t n = values_.size();
    std::vector<const char*> values(n);
    std::vector<int> lengths(n);
    for (std::size_t i = 0; i < n; ++i) {
      values[i] = null_[i] ? nullptr : values_[i].c_str();
      lengths[i] = static_cast<int>(values_[i].size());
    }
    PGconn* conn = connection_->handle();
    const int count = static_cast<int>(n);
    result_ = name_.empty() ? PQexecParams(conn, sql_.c_str(), count, types_.data(), values.data(),
                                           lengths.data(), binary_.data(), 0)
                            : PQexecPrepared(conn, name_.c_str(), count, values.data(),
                                             lengths.data(), binary_.data(), 0);
    const ExecStatusType status = result_ != nullptr ? PQresultStatus(result_) : PGRES_FATAL_ERROR;
    if (status == PGRES_TUPLES_OK || status == PGRES_COMMAND_OK) return api::Status::Ok();
    api::Status error = connection_->StatusFromResult(result_, "");
    PQclear(result_);
    result_ = nullptr;
    return error;
  }

  PostgresConnection* connection_;
  std::string name_;  // empty: not prepared on the server
  std::string sql_;
  std::vector<Oid> types_;  // 0 = the server infers it
  std::vector<std::string> values_;
  std::vector<bool> null_;
  std::vector<int> binary_;
  int bad_index_ = 0;
  bool executed_ = false;
  PGresult* result_ = nullptr;
  int row_ = -1;
  // Decoded BLOBs of the current row (Blob's spans stay valid until the next
  // Step or Release).
  mutable std::vector<std::vector<std::byte>> blobs_;
};

api::Result<std::unique_ptr<PostgresListener>> PostgresListener::Start(
    const std::string& url, const std::string& channel,
    std::function<void(std::string_view payload)> on_payload) {
  std::unique_ptr<PostgresListener> listener(
      new PostgresListener(url, channel, std::move(on_payload)));
  pg_conn* conn = listener->Connect();
  if (conn == nullptr) {
    return api::Status::Unavailable("cannot listen for notifications at " + RedactedUrl(url));
  }
  PostgresListener* self = listener.get();
  listener->thread_ = std::thread([self, conn] { self->Loop(conn); });
  return listener;
}

PostgresListener::~PostgresListener() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

pg_conn* PostgresListener::Connect() const {
  PGconn* conn = PQconnectdb(url_.c_str());
  if (PQstatus(conn) != CONNECTION_OK) {
    PQfinish(conn);
    return nullptr;
  }
  PQsetNoticeProcessor(conn, IgnoreNotice, nullptr);
  PGresult* result = PQexec(conn, ("LISTEN " + channel_).c_str());
  const bool ok = PQresultStatus(result) == PGRES_COMMAND_OK;
  PQclear(result);
  if (!ok) {
    PQfinish(conn);
    return nullptr;
  }
  return conn;
}

void PostgresListener::Loop(pg_conn* conn) {
  while (!stop_) {
    if (conn == nullptr) {  // the server went: try again twice a second
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
      conn = Connect();
      continue;
    }
    pollfd waiting{PQsocket(conn), POLLIN, 0};
    if (::poll(&waiting, 1, 200) < 0 || PQconsumeInput(conn) == 0 ||
        PQstatus(conn) != CONNECTION_OK) {
      PQfinish(conn);
      conn = nullptr;
      continue;
    }
    while (PGnotify* notification = PQnotifies(conn)) {
      on_payload_(notification->extra != nullptr ? notification->extra : "");
      PQfreemem(notification);
    }
  }
  if (conn != nullptr) PQfinish(conn);
}

std::string PostgresParameters(std::string_view sql, std::vector<bool>& used) {
  std::string out;
  out.reserve(sql.size() + 8);
  used.clear();
  int sequential = 0;
  for (std::size_t i = 0; i < sql.size(); ++i) {
    const char c = sql[i];
    if (c == '\'' || c == '"') {  // quoted text or identifier, '' / "" escape by doubling
      const std::size_t close = sql.find(c, i + 1);
      const std::size_t end = close == std::string_view::npos ? sql.size() : close + 1;
      out.append(sql.substr(i, end - i));
      i = end - 1;
    } else if (c == '-' && i + 1 < sql.size() && sql[i + 1] == '-') {
      const std::size_t newline = sql.find('\n', i);
      const std::size_t end = newline == std::string_view::npos ? sql.size() : newline;
      out.append(sql.substr(i, end - i));
      i = end - 1;
    } else if (c == '?') {
      std::size_t j = i + 1;
      int number = 0;
      while (j < sql.size() && std::isdigit(static_cast<unsigned char>(sql[j]))) {
        number = number * 10 + (sql[j] - '0');
        ++j;
      }
      if (j == i + 1) number = ++sequential;
      if (number >= 1) {
        if (used.size() < static_cast<std::size_t>(number)) used.resize(number, false);
        used[static_cast<std::size_t>(number - 1)] = true;
      }
      out += '$';
      out += std::to_string(number);
      i = j - 1;
    } else {
      out += c;
    }
  }
  return out;
}

std::string RedactedUrl(std::string_view url) {
  const std::size_t scheme = url.find("://");
  const std::size_t at = url.find('@');
  if (scheme == std::string_view::npos || at == std::string_view::npos || at < scheme) {
    return std::string(url);
  }
  const std::size_t colon = url.find(':', scheme + 3);
  if (colon == std::string_view::npos || colon > at) return std::string(url);
  return std::string(url.substr(0, colon + 1)) + "***" + std::string(url.substr(at));
}

api::Result<ClientConnection> SplitPassword(const std::string& url) {
  // libpq's reason is left out: it may quote the password.
  char* error = nullptr;
  PQconninfoOption* options = PQconninfoParse(url.c_str(), &error);
  PQfreemem(error);
  if (options == nullptr) {
    return api::Status::InvalidArgument("cannot read the PostgreSQL URL " + RedactedUrl(url) +
                                        " (postgresql://user[:password]@host[:port]/database[?…])");
  }
  ClientConnection client;
  for (const PQconninfoOption* option = options; option->keyword != nullptr; ++option) {
    if (option->val == nullptr || *option->val == '\0') continue;
    if (std::strcmp(option->keyword, "password") == 0) {
      client.password = option->val;
      continue;
    }
    // keyword='value', with ' and \ escaped by a backslash (libpq's rules).
    if (!client.conninfo.empty()) client.conninfo += ' ';
    client.conninfo += option->keyword;
    client.conninfo += "='";
    for (const char* c = option->val; *c != '\0'; ++c) {
      if (*c == '\'' || *c == '\\') client.conninfo += '\\';
      client.conninfo += *c;
    }
    client.conninfo += '\'';
  }
  PQconninfoFree(options);
  return client;
}

api::Result<std::unique_ptr<PostgresConnection>> PostgresConnection::Open(const std::string& url) {
  PGconn* conn = PQconnectdb(url.c_str());
  std::unique_ptr<PostgresConnection> connection(new PostgresConnection(conn, url));
  if (conn == nullptr || PQstatus(conn) != CONNECTION_OK) {
    std::string detail = conn != nullptr ? PQerrorMessage(conn) : "out of memory";
    while (!detail.empty() && std::isspace(static_cast<unsigned char>(detail.back()))) {
      detail.pop_back();
    }
    return api::Status::Unavailable("cannot connect to PostgreSQL at " + RedactedUrl(url) + ": " +
                                    detail);
  }
  PQsetNoticeProcessor(conn, IgnoreNotice, nullptr);
  // Text is compared byte by byte as in SQLite (the *_utc columns are
  // COLLATE "C" in the schema too); times are text, so the zone is moot.
  // random_page_cost 1.1, PostgreSQL's advice for SSD storage: with the
  // default 4 the planner scans a small table (10,000 subject revisions)
  // rather than seek 51 rows by index, and a 0.2 ms page took 2.6 ms.
  if (auto status = connection->ExecScript("SET client_encoding = 'UTF8';"
                                            " SET random_page_cost = 1.1");
      !status.ok()) {
    return status;
  }
  return connection;
}

PostgresConnection::~PostgresConnection() {
  cache_.clear();
  PQfinish(conn_);
}

api::Status PostgresConnection::EnsureOpen() {
  if (PQstatus(conn_) == CONNECTION_OK) return api::Status::Ok();
  cache_.clear();  // the server forgot the prepared statements
  PQreset(conn_);
  if (PQstatus(conn_) != CONNECTION_OK) {
    return api::Status::Unavailable("lost the connection to PostgreSQL at " + RedactedUrl(url_) +
                                    " and cannot reconnect: " + PQerrorMessage(conn_));
  }
  PQsetNoticeProcessor(conn_, IgnoreNotice, nullptr);
  return api::Status::Ok();
}

api::Result<Statement> PostgresConnection::Prepare(std::string_view sql) {
  auto it = cache_.find(std::string(sql));
  if (it != cache_.end() && !it->second->in_use) {
    it->second->in_use = true;
    return Statement(it->second.get(), /*owned=*/false);
  }
  std::vector<bool> used;
  std::string translated = PostgresParameters(sql, used);
  const int parameters = static_cast<int>(used.size());
  // A number the SQL skips (a filter left out of this shape) gets a type of
  // its own, text, so the server does not ask what it is; its value is sent
  // and ignored.
  std::vector<Oid> types(used.size(), 0);
  for (std::size_t i = 0; i < used.size(); ++i) {
    if (!used[i]) types[i] = 25;  // text
  }
  if (it != cache_.end()) {  // the cached one is busy: send this one's text each time
    return Statement(new PostgresStatement(this, "", std::move(translated), std::move(types)),
                     /*owned=*/true);
  }
  std::string name = "s" + std::to_string(next_statement_++);
  PGresult* result =
      PQprepare(conn_, name.c_str(), translated.c_str(), parameters, types.data());
  const bool ok = result != nullptr && PQresultStatus(result) == PGRES_COMMAND_OK;
  api::Status status = ok ? api::Status::Ok() : StatusFromResult(result, "preparing a statement");
  PQclear(result);
  if (!status.ok()) return status;
  auto prepared = std::make_unique<PostgresStatement>(this, std::move(name),
                                                     std::move(translated), std::move(types));
  prepared->in_use = true;
  StatementImpl* impl = prepared.get();
  cache_.emplace(std::string(sql), std::move(prepared));
  return Statement(impl, /*owned=*/false);
}

api::Status PostgresConnection::ExecScript(const std::string& sql) {
  PGresult* result = PQexec(conn_, sql.c_str());
  const ExecStatusType status = result != nullptr ? PQresultStatus(result) : PGRES_FATAL_ERROR;
  api::Status out = status == PGRES_COMMAND_OK || status == PGRES_TUPLES_OK
                        ? api::Status::Ok()
                        : StatusFromResult(result, "");
  PQclear(result);
  return out;
}

bool PostgresConnection::autocommit() const { return PQtransactionStatus(conn_) == PQTRANS_IDLE; }

api::Status PostgresConnection::StatusFromResult(const pg_result* result,
                                                 std::string_view context) {
  std::string message(context);
  if (!message.empty()) message += ": ";
  const char* primary =
      result != nullptr ? PQresultErrorField(result, PG_DIAG_MESSAGE_PRIMARY) : nullptr;
  std::string detail = primary != nullptr ? primary : PQerrorMessage(conn_);
  while (!detail.empty() && std::isspace(static_cast<unsigned char>(detail.back()))) {
    detail.pop_back();
  }
  message += detail;
  if (PQstatus(conn_) != CONNECTION_OK) {
    return api::Status::Unavailable("lost the connection to PostgreSQL: " + message);
  }
  const char* state = result != nullptr ? PQresultErrorField(result, PG_DIAG_SQLSTATE) : nullptr;
  const std::string sqlstate = state != nullptr ? state : "";
  const std::string sqlclass = sqlstate.substr(0, 2);
  if (sqlstate == "40001" || sqlstate == "40P01" || sqlstate == "55P03") {
    NoteBusy();
    return api::Status::Unavailable("database is busy: " + message);
  }
  if (sqlstate == "23505") {
    NoteUniqueConflict();
    return api::Status::AlreadyExists(message);
  }
  if (sqlstate == "23503") {
    return api::Status::InvalidArgument(message + " (a referenced row does not exist)");
  }
  if (sqlclass == "23" || sqlclass == "22") return api::Status::InvalidArgument(message);
  if (sqlstate == "P0001") return api::Status::FailedPrecondition(message);  // append-only
  if (sqlstate == "XX001" || sqlstate == "XX002") return api::Status::DataLoss(message);
  if (sqlclass == "08" || sqlclass == "53" || sqlclass == "57") {
    return api::Status::Unavailable(message);
  }
  return api::Status::Internal(message);
}

}  // namespace fesbench::storage
