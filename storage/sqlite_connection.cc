#include "storage/sqlite_connection.h"

#include <sqlite3.h>

namespace fesbench::storage {

class SqliteStatement final : public StatementImpl {
 public:
  SqliteStatement(sqlite3_stmt* stmt, SqliteConnection* connection)
      : stmt_(stmt), connection_(connection) {}
  ~SqliteStatement() override { sqlite3_finalize(stmt_); }

  void BindInt64(int index, std::int64_t value) override {
    Note(sqlite3_bind_int64(stmt_, index, value));
  }
  void BindDouble(int index, double value) override {
    Note(sqlite3_bind_double(stmt_, index, value));
  }
  void BindText(int index, std::string_view text) override {
    // An empty view may have a null data pointer, which SQLite would bind as
    // NULL; an empty string must stay an empty TEXT.
    const char* data = text.data() != nullptr ? text.data() : "";
    Note(sqlite3_bind_text64(stmt_, index, data, text.size(), SQLITE_TRANSIENT, SQLITE_UTF8));
  }
  void BindBlob(int index, std::span<const std::byte> blob) override {
    // A zero-length blob must still be a BLOB, not NULL: pass a valid pointer.
    static const std::byte kEmpty{};
    const void* data = blob.empty() ? &kEmpty : blob.data();
    Note(sqlite3_bind_blob64(stmt_, index, data, blob.size(), SQLITE_TRANSIENT));
  }
  void BindNull(int index) override { Note(sqlite3_bind_null(stmt_, index)); }

  api::Result<bool> Step() override {
    if (bind_error_ != 0) return connection_->StatusFromCode(bind_error_, "binding a parameter");
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    return connection_->StatusFromCode(rc, "");
  }

  bool IsNull(int column) const override {
    return sqlite3_column_type(stmt_, column) == SQLITE_NULL;
  }
  std::int64_t Int64(int column) const override { return sqlite3_column_int64(stmt_, column); }
  double Double(int column) const override { return sqlite3_column_double(stmt_, column); }
  std::string Text(int column) const override {
    const auto* text = sqlite3_column_text(stmt_, column);
    const int size = sqlite3_column_bytes(stmt_, column);
    return text == nullptr
               ? std::string()
               : std::string(reinterpret_cast<const char*>(text), static_cast<std::size_t>(size));
  }
  std::span<const std::byte> Blob(int column) const override {
    const void* data = sqlite3_column_blob(stmt_, column);
    const int size = sqlite3_column_bytes(stmt_, column);
    if (data == nullptr) return {};
    return {static_cast<const std::byte*>(data), static_cast<std::size_t>(size)};
  }

  void Release() override {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
    bind_error_ = 0;
    in_use = false;
  }

 private:
  void Note(int rc) {
    if (rc != SQLITE_OK && bind_error_ == 0) bind_error_ = rc;
  }

  sqlite3_stmt* stmt_;
  SqliteConnection* connection_;
  int bind_error_ = 0;  // first SQLite error from a Bind call, reported by Step
};

api::Result<std::unique_ptr<SqliteConnection>> SqliteConnection::Open(const std::string& path,
                                                                      int flags,
                                                                      int busy_timeout_ms) {
  sqlite3* db = nullptr;
  const int rc = sqlite3_open_v2(path.c_str(), &db, flags, nullptr);
  std::unique_ptr<SqliteConnection> connection(new SqliteConnection(db));
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

SqliteConnection::~SqliteConnection() {
  cache_.clear();
  sqlite3_close_v2(db_);
}

api::Result<Statement> SqliteConnection::Prepare(std::string_view sql) {
  auto it = cache_.find(std::string(sql));
  if (it != cache_.end() && !it->second->in_use) {
    it->second->in_use = true;
    return Statement(it->second.get(), /*owned=*/false);
  }
  sqlite3_stmt* stmt = nullptr;
  const int rc = sqlite3_prepare_v3(db_, sql.data(), static_cast<int>(sql.size()),
                                    SQLITE_PREPARE_PERSISTENT, &stmt, nullptr);
  if (rc != SQLITE_OK) return StatusFromCode(rc, "preparing a statement");
  auto prepared = std::make_unique<SqliteStatement>(stmt, this);
  if (it != cache_.end()) return Statement(prepared.release(), /*owned=*/true);  // cached one busy
  prepared->in_use = true;
  StatementImpl* impl = prepared.get();
  cache_.emplace(std::string(sql), std::move(prepared));
  return Statement(impl, /*owned=*/false);
}

api::Status SqliteConnection::ExecScript(const std::string& sql) {
  const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, nullptr);
  if (rc == SQLITE_OK) return api::Status::Ok();
  return StatusFromCode(rc, "");
}

bool SqliteConnection::autocommit() const { return sqlite3_get_autocommit(db_) != 0; }

api::Status SqliteConnection::StatusFromCode(int rc, std::string_view context) {
  std::string message(context);
  const char* detail = db_ != nullptr ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
  if (!message.empty()) message += ": ";
  message += detail != nullptr ? detail : sqlite3_errstr(rc);
  switch (rc & 0xff) {
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
      NoteBusy();
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

}  // namespace fesbench::storage
