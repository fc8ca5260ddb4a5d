#include "storage/connection.h"

#include <sqlite3.h>

#include <bit>
#include <cstring>

namespace fesbench::storage {

// ---------------------------------------------------------------- Statement

Statement::Statement(sqlite3_stmt* stmt, Connection* connection, bool owned)
    : stmt_(stmt), connection_(connection), owned_(owned) {}

Statement::Statement(Statement&& other) noexcept
    : stmt_(other.stmt_),
      connection_(other.connection_),
      owned_(other.owned_),
      bind_error_(other.bind_error_) {
  other.stmt_ = nullptr;
}

Statement::~Statement() {
  if (stmt_ == nullptr) return;
  if (owned_) {
    sqlite3_finalize(stmt_);
  } else {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
    connection_->Release(stmt_);
  }
}

Statement& Statement::Bind(int index, std::int64_t value) {
  const int rc = sqlite3_bind_int64(stmt_, index, value);
  if (rc != SQLITE_OK && bind_error_ == 0) bind_error_ = rc;
  return *this;
}

Statement& Statement::Bind(int index, double value) {
  const int rc = sqlite3_bind_double(stmt_, index, value);
  if (rc != SQLITE_OK && bind_error_ == 0) bind_error_ = rc;
  return *this;
}

Statement& Statement::Bind(int index, std::string_view text) {
  // An empty view may have a null data pointer, which SQLite would bind as
  // NULL; an empty string must stay an empty TEXT.
  const char* data = text.data() != nullptr ? text.data() : "";
  const int rc =
      sqlite3_bind_text64(stmt_, index, data, text.size(), SQLITE_TRANSIENT, SQLITE_UTF8);
  if (rc != SQLITE_OK && bind_error_ == 0) bind_error_ = rc;
  return *this;
}

Statement& Statement::BindBlob(int index, std::span<const std::byte> blob) {
  // A zero-length blob must still be a BLOB, not NULL: pass a valid pointer.
  static const std::byte kEmpty{};
  const void* data = blob.empty() ? &kEmpty : blob.data();
  const int rc = sqlite3_bind_blob64(stmt_, index, data, blob.size(), SQLITE_TRANSIENT);
  if (rc != SQLITE_OK && bind_error_ == 0) bind_error_ = rc;
  return *this;
}

Statement& Statement::BindNull(int index) {
  const int rc = sqlite3_bind_null(stmt_, index);
  if (rc != SQLITE_OK && bind_error_ == 0) bind_error_ = rc;
  return *this;
}

api::Result<bool> Statement::Step() {
  if (bind_error_ != 0) return connection_->StatusFromCode(bind_error_, "binding a parameter");
  const int rc = sqlite3_step(stmt_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  return connection_->StatusFromCode(rc, "");
}

api::Status Statement::Run() {
  while (true) {
    auto row = Step();
    if (!row.ok()) return row.status();
    if (!*row) return api::Status::Ok();
  }
}

bool Statement::IsNull(int column) const {
  return sqlite3_column_type(stmt_, column) == SQLITE_NULL;
}
std::int64_t Statement::Int64(int column) const { return sqlite3_column_int64(stmt_, column); }
double Statement::Double(int column) const { return sqlite3_column_double(stmt_, column); }
std::string Statement::Text(int column) const {
  const auto* text = sqlite3_column_text(stmt_, column);
  const int size = sqlite3_column_bytes(stmt_, column);
  return text == nullptr
             ? std::string()
             : std::string(reinterpret_cast<const char*>(text), static_cast<std::size_t>(size));
}
std::optional<std::int64_t> Statement::OptionalInt64(int column) const {
  if (IsNull(column)) return std::nullopt;
  return Int64(column);
}
std::optional<double> Statement::OptionalDouble(int column) const {
  if (IsNull(column)) return std::nullopt;
  return Double(column);
}
std::span<const std::byte> Statement::Blob(int column) const {
  const void* data = sqlite3_column_blob(stmt_, column);
  const int size = sqlite3_column_bytes(stmt_, column);
  if (data == nullptr) return {};
  return {static_cast<const std::byte*>(data), static_cast<std::size_t>(size)};
}

// --------------------------------------------------------------- Connection

api::Result<std::unique_ptr<Connection>> Connection::Open(const std::string& path, int flags,
                                                          int busy_timeout_ms) {
  sqlite3* db = nullptr;
  const int rc = sqlite3_open_v2(path.c_str(), &db, flags, nullptr);
  std::unique_ptr<Connection> connection(new Connection(db));
  if (rc != SQLITE_OK) {
    return connection->StatusFromCode(rc, "opening " + path);
  }
  sqlite3_extended_result_codes(db, 1);
  sqlite3_busy_timeout(db, busy_timeout_ms);
  if (auto status = connection->ExecScript("PRAGMA foreign_keys = ON;"); !status.ok()) {
    return status;
  }
  return connection;
}

Connection::~Connection() {
  for (auto& [sql, entry] : cache_) sqlite3_finalize(entry.stmt);
  sqlite3_close_v2(db_);
}

api::Result<Statement> Connection::Prepare(std::string_view sql) {
  auto it = cache_.find(std::string(sql));
  if (it != cache_.end() && !it->second.in_use) {
    it->second.in_use = true;
    return Statement(it->second.stmt, this, /*owned=*/false);
  }
  sqlite3_stmt* stmt = nullptr;
  const int rc = sqlite3_prepare_v3(db_, sql.data(), static_cast<int>(sql.size()),
                                    SQLITE_PREPARE_PERSISTENT, &stmt, nullptr);
  if (rc != SQLITE_OK) return StatusFromCode(rc, "preparing a statement");
  if (it != cache_.end()) return Statement(stmt, this, /*owned=*/true);  // cached one is busy
  cache_.emplace(std::string(sql), CacheEntry{stmt, true});
  return Statement(stmt, this, /*owned=*/false);
}

void Connection::Release(sqlite3_stmt* stmt) {
  const char* sql = sqlite3_sql(stmt);
  if (sql == nullptr) return;
  auto it = cache_.find(sql);
  if (it != cache_.end() && it->second.stmt == stmt) it->second.in_use = false;
}

api::Status Connection::ExecScript(const std::string& sql) {
  const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, nullptr);
  if (rc == SQLITE_OK) return api::Status::Ok();
  return StatusFromCode(rc, "");
}

api::Result<std::string> Connection::QueryText(const std::string& sql) {
  auto statement = Prepare(sql);
  if (!statement.ok()) return statement.status();
  auto row = statement->Step();
  if (!row.ok()) return row.status();
  if (!*row) return std::string();
  return statement->Text(0);
}

std::int64_t Connection::LastInsertRowId() const { return sqlite3_last_insert_rowid(db_); }

bool Connection::autocommit() const { return sqlite3_get_autocommit(db_) != 0; }

api::Status Connection::StatusFromCode(int rc, std::string_view context) {
  std::string message(context);
  const char* detail = db_ != nullptr ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
  if (!message.empty()) message += ": ";
  message += detail != nullptr ? detail : sqlite3_errstr(rc);
  switch (rc & 0xff) {
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
      busy_seen_ = true;
      return api::Status::Unavailable("database is busy: " + message);
    case SQLITE_CONSTRAINT:
      switch (rc) {
        case SQLITE_CONSTRAINT_UNIQUE:
        case SQLITE_CONSTRAINT_PRIMARYKEY:
          return api::Status::AlreadyExists(message);
        case SQLITE_CONSTRAINT_TRIGGER:
          return api::Status::FailedPrecondition(message);
        case SQLITE_CONSTRAINT_FOREIGNKEY:
          return api::Status::InvalidArgument(message + " (a referenced row does not exist)");
        default:
          return api::Status::InvalidArgument(message);
      }
    case SQLITE_CORRUPT:
    case SQLITE_NOTADB:
      return api::Status::DataLoss(message);
    case SQLITE_IOERR:
    case SQLITE_FULL:
    case SQLITE_CANTOPEN:
    case SQLITE_READONLY:
    case SQLITE_PROTOCOL:
      return api::Status::Unavailable(message);
    case SQLITE_TOOBIG:
    case SQLITE_RANGE:
    case SQLITE_MISMATCH:
      return api::Status::InvalidArgument(message);
    default:
      return api::Status::Internal(message);
  }
}

// ------------------------------------------------------------------ samples

std::vector<std::byte> PackFloat64Le(std::span<const double> samples) {
  std::vector<std::byte> blob(samples.size() * sizeof(double));
  if constexpr (std::endian::native == std::endian::little) {
    if (!samples.empty()) std::memcpy(blob.data(), samples.data(), blob.size());
  } else {
    for (std::size_t i = 0; i < samples.size(); ++i) {
      const auto bits = std::bit_cast<std::uint64_t>(samples[i]);
      for (int b = 0; b < 8; ++b) {
        blob[i * 8 + static_cast<std::size_t>(b)] =
            static_cast<std::byte>((bits >> (8 * b)) & 0xff);
      }
    }
  }
  return blob;
}

std::optional<std::vector<double>> UnpackFloat64Le(std::span<const std::byte> blob) {
  if (blob.size() % sizeof(double) != 0) return std::nullopt;
  std::vector<double> samples(blob.size() / sizeof(double));
  if constexpr (std::endian::native == std::endian::little) {
    if (!blob.empty()) std::memcpy(samples.data(), blob.data(), blob.size());
  } else {
    for (std::size_t i = 0; i < samples.size(); ++i) {
      std::uint64_t bits = 0;
      for (int b = 0; b < 8; ++b) {
        bits |= static_cast<std::uint64_t>(blob[i * 8 + static_cast<std::size_t>(b)]) << (8 * b);
      }
      samples[i] = std::bit_cast<double>(bits);
    }
  }
  return samples;
}

}  // namespace fesbench::storage
