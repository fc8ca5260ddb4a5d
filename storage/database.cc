#include "storage/database.h"

#include <sqlite3.h>
#include <unistd.h>

#include <algorithm>
#include <random>
#include <sstream>
#include <exception>
#include <filesystem>
#include <system_error>

#include "storage/file_lock.h"
#include "storage/migrations.h"
#include "storage/postgres_connection.h"
#include "storage/private_files.h"
#include "storage/sqlite_connection.h"

namespace fesbench::storage {
namespace {

using Clock = std::chrono::steady_clock;

// The reader connection this thread holds inside Database::Read, so a Read
// nested in a Read reuses it instead of taking a second one from the pool
// (which could exhaust the pool and deadlock).
thread_local const Database* tls_reader_owner = nullptr;
thread_local Connection* tls_reader = nullptr;

// Every problem row of PRAGMA integrity_check (at most `limit`), or empty
// when the check says "ok".
api::Result<std::vector<std::string>> IntegrityProblems(Connection& connection, int limit) {
  auto statement = connection.Prepare("PRAGMA integrity_check(" + std::to_string(limit) + ")");
  if (!statement.ok()) return statement.status();
  std::vector<std::string> problems;
  while (true) {
    auto row = statement->Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    std::string text = statement->Text(0);
    if (text != "ok") problems.push_back(std::move(text));
  }
  return problems;
}

api::Status CorruptStatus(const std::string& path, const std::string& detail) {
  return api::Status::DataLoss("database file '" + path + "' is corrupt (" + detail +
                               "); refusing to use it: restore it from a backup");
}

// Turns any failure while touching a possibly corrupt file into kDataLoss
// when SQLite says the file is corrupt or not a database.
api::Status CheckedOpenStep(api::Status status, const std::string& path) {
  if (status.ok() || status.code() != api::ErrorCode::kDataLoss) return status;
  return CorruptStatus(path, status.message());
}

// The schema version: SQLite's user_version, or on PostgreSQL the newest
// row of schema_migrations (0 before the first migration).
api::Result<int> UserVersion(Connection& connection) {
  if (connection.engine() == Engine::kPostgres) {
    auto exists = connection.QueryText("SELECT to_regclass('schema_migrations') IS NOT NULL");
    if (!exists.ok()) return exists.status();
    if (*exists != "t") return 0;
    auto text = connection.QueryText("SELECT COALESCE(MAX(version), 0) FROM schema_migrations");
    if (!text.ok()) return text.status();
    return std::stoi(text->empty() ? std::string("0") : *text);
  }
  auto text = connection.QueryText("PRAGMA user_version");
  if (!text.ok()) return text.status();
  return std::stoi(text->empty() ? std::string("0") : *text);
}

const std::vector<Migration>& MigrationsOf(Engine engine) {
  return engine == Engine::kPostgres ? PostgresMigrations() : AllMigrations();
}

// The key of the session lock that lets one server at a time migrate a
// PostgreSQL database (several servers may start together).
constexpr const char* kMigrationLock = "SELECT pg_advisory_lock(7262011809)";
constexpr const char* kMigrationUnlock = "SELECT pg_advisory_unlock(7262011809)";

api::Status PostgresOnly(const char* what) {
  return api::Status::FailedPrecondition(
      std::string(what) +
      " is for the embedded SQLite file; back up and restore a PostgreSQL database with "
      "pg_dump and pg_restore (README, \"Backups\")");
}

// Copies the whole database behind `source` into `destination` with the
// backup API, retrying while either side is busy.
api::Status CopyDatabase(SqliteConnection& source, SqliteConnection& destination,
                         Clock::time_point deadline) {
  auto delay = std::chrono::milliseconds(1);
  while (true) {
    sqlite3_backup* backup =
        sqlite3_backup_init(destination.handle(), "main", source.handle(), "main");
    if (backup == nullptr) {
      return destination.StatusFromCode(sqlite3_extended_errcode(destination.handle()),
                                        "starting a backup");
    }
    const int step_rc = sqlite3_backup_step(backup, -1);
    const int finish_rc = sqlite3_backup_finish(backup);
    if (step_rc == SQLITE_DONE && finish_rc == SQLITE_OK) return api::Status::Ok();
    const int rc = step_rc == SQLITE_DONE ? finish_rc : step_rc;
    const int primary = rc & 0xff;
    if ((primary == SQLITE_BUSY || primary == SQLITE_LOCKED) && Clock::now() < deadline) {
      std::this_thread::sleep_for(delay);
      delay = std::min(delay * 2, std::chrono::milliseconds(50));
      continue;
    }
    api::Status status = destination.StatusFromCode(rc, "copying the database");
    destination.ClearBusy();
    if (status.code() == api::ErrorCode::kUnavailable) {
      return api::Status::Unavailable("database stayed busy during the copy: " + status.message());
    }
    return status;
  }
}

// A backup written to `temporary` becomes `destination_path` only when it is
// complete (`status` ok); otherwise, or if the move fails, the temporary goes.
api::Status FinishBackup(const api::Status& status, const std::string& temporary,
                         const std::string& destination_path) {
  namespace fs = std::filesystem;
  std::error_code ignored;
  if (!status.ok()) {
    fs::remove(temporary, ignored);
    return status;
  }
  std::error_code error;
  fs::rename(temporary, destination_path, error);
  if (error) {
    fs::remove(temporary, ignored);
    return api::Status::Unavailable("cannot move the backup to '" + destination_path +
                                    "': " + error.message());
  }
  return api::Status::Ok();
}

}  // namespace

Database::Database(DatabaseOptions options) : options_(std::move(options)) {
  if (options_.clock == nullptr) options_.clock = api::Clock::Real();
}

Database::~Database() {
  // Free the bench at once (closing the connection frees it only once the
  // server has noticed), so a restarted server can take it straight away.
  notifications_.reset();
  bench_lock_.reset();
  readers_.clear();
  writer_.reset();
  file_lock_.reset();  // last: the file is free only once every connection is closed
}

api::UtcTime Database::Now() const { return options_.clock->UtcNow(); }

bool IsPostgresUrl(std::string_view location) {
  return location.starts_with("postgresql://") || location.starts_with("postgres://");
}

api::Result<std::unique_ptr<Database>> Database::Open(DatabaseOptions options) {
  if (options.path.empty()) return api::Status::InvalidArgument("empty database path", "path");
  if (options.reader_count < 1) {
    return api::Status::InvalidArgument("reader_count must be at least 1", "reader_count");
  }
  if (options.target_schema_version && (*options.target_schema_version < 0 ||
                                        *options.target_schema_version > LatestSchemaVersion())) {
    return api::Status::InvalidArgument(
        "target_schema_version must be in [0, " + std::to_string(LatestSchemaVersion()) + "]",
        "target_schema_version");
  }
  std::unique_ptr<Database> database(new Database(std::move(options)));
  if (auto status = database->Initialise(); !status.ok()) return status;
  return database;
}

api::Status Database::Initialise() {
  if (engine() == Engine::kPostgres) return InitialisePostgres();
  const std::string& path = options_.path;
  const int timeout_ms = static_cast<int>(options_.busy_timeout.count());
  // Before anything touches the file: a second server on it is refused here.
  if (options_.lock_file) {
    auto lock = DatabaseFileLock::Acquire(path);
    if (!lock.ok()) return lock.status();
    file_lock_ = std::move(*lock);
  }
  if (auto status = MakePrivateFiles(); !status.ok()) return status;
  auto writer = SqliteConnection::Open(
      path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, timeout_ms);
  if (!writer.ok()) return CheckedOpenStep(writer.status(), path);
  writer_ = std::move(*writer);

  // The first statement that reads the file: a file that is not a database
  // fails here with SQLITE_NOTADB.
  auto mode = writer_->QueryText("PRAGMA journal_mode = WAL");
  if (!mode.ok()) return CheckedOpenStep(mode.status(), path);
  if (*mode != "wal") {
    return api::Status::Unavailable("cannot switch '" + path + "' to WAL (journal_mode " + *mode +
                                    ")");
  }
  const char* synchronous = options_.synchronous == Synchronous::kFull
                                ? "PRAGMA synchronous = FULL"
                                : "PRAGMA synchronous = NORMAL";
  if (auto status = writer_->ExecScript(synchronous); !status.ok()) return status;

  if (options_.check_integrity) {
    auto problems = IntegrityProblems(*writer_, 5);
    if (!problems.ok()) return CheckedOpenStep(problems.status(), path);
    if (!problems->empty()) {
      std::string detail = "integrity_check: ";
      for (std::size_t i = 0; i < problems->size(); ++i) {
        detail += (i == 0 ? "" : "; ") + (*problems)[i];
      }
      return CorruptStatus(path, detail);
    }
  }

  if (auto status = CheckedOpenStep(Migrate(options_.target_schema_version), path); !status.ok()) {
    return status;
  }

  for (int i = 0; i < options_.reader_count; ++i) {
    auto reader = SqliteConnection::Open(path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX, timeout_ms);
    if (!reader.ok()) return reader.status();
    if (auto status = (*reader)->ExecScript("PRAGMA query_only = ON"); !status.ok()) {
      return status;
    }
    free_readers_.push_back(reader->get());
    readers_.push_back(std::move(*reader));
  }
  return api::Status::Ok();
}

api::Status Database::InitialisePostgres() {
  // One server per bench, before anything else: a session lock on the bench
  // id, held and watched for as long as this process has the database.
  BenchLockOptions lock_options;
  lock_options.url = options_.path;
  lock_options.bench_id = options_.bench_id;
  lock_options.check_interval = options_.bench_lock_check_interval;
  auto lock = PostgresBenchLock::Acquire(std::move(lock_options));
  if (!lock.ok()) return lock.status();
  bench_lock_ = std::move(*lock);
  auto writer = PostgresConnection::Open(options_.path);
  if (!writer.ok()) return writer.status();
  writer_ = std::move(*writer);
  // Several servers may start at once: one migrates, the others wait for it.
  if (auto status = writer_->ExecScript(kMigrationLock); !status.ok()) return status;
  api::Status migrated = Migrate(options_.target_schema_version);
  api::Status unlocked = writer_->ExecScript(kMigrationUnlock);
  if (!migrated.ok()) return migrated;
  if (!unlocked.ok()) return unlocked;
  // Sets stored by the other servers, as events, so nobody polls.
  instance_id_ = options_.bench_id + "/" + std::to_string(::getpid()) + "/" +
                 std::to_string(std::random_device{}());
  auto listener = PostgresListener::Start(
      options_.path, "fesbench_parameter_sets", [this](std::string_view payload) {
        std::istringstream in{std::string(payload)};
        std::string origin;
        ParameterSetStored event;
        if (!(in >> origin >> event.id >> event.subject_id >> event.leg_id)) return;
        int approval = 0;  // absent from an older server's payload
        if (in >> approval) event.approval = approval == 1;
        if (origin != instance_id_) CallParameterSetListener(event);
      });
  if (!listener.ok()) return listener.status();
  notifications_ = std::move(*listener);
  for (int i = 0; i < options_.reader_count; ++i) {
    auto reader = PostgresConnection::Open(options_.path);
    if (!reader.ok()) return reader.status();
    free_readers_.push_back(reader->get());
    readers_.push_back(std::move(*reader));
  }
  return api::Status::Ok();
}

// The database file is created 0600 before SQLite opens it (its -wal and
// -shm then take the same mode); the files of an older version that group
// or others can read are narrowed to 0600 and said in open_notes().
api::Status Database::MakePrivateFiles() {
  const std::string& path = options_.path;
  if (auto status = CreatePrivateFile(path); !status.ok()) return status;
  for (const std::string& file : {path, path + "-wal", path + "-shm"}) {
    auto narrowed = NarrowToOwner(file);
    if (!narrowed.ok()) return narrowed.status();
    if (*narrowed) {
      open_notes_.push_back("narrowed '" + file + "' from mode " + ModeText(**narrowed) +
                            " to 0600 (the database is readable by its owner only)");
    }
  }
  return api::Status::Ok();
}

void Database::SetBenchLockListener(BenchLockListener listener) {
  if (bench_lock_ != nullptr) bench_lock_->SetListener(std::move(listener));
}

Engine Database::engine() const {
  return IsPostgresUrl(options_.path) ? Engine::kPostgres : Engine::kSqlite;
}

api::Status Database::Migrate(std::optional<int> target) {
  const int latest = LatestSchemaVersion();
  const int goal = target.value_or(latest);
  int version = 0;
  auto read = RunOnWriter([&](Connection& c) -> api::Status {
    auto v = UserVersion(c);
    if (!v.ok()) return v.status();
    version = *v;
    return api::Status::Ok();
  });
  if (!read.ok()) return read;
  if (version > latest) {
    return api::Status::FailedPrecondition("database schema version " + std::to_string(version) +
                                           " is newer than this software's (" +
                                           std::to_string(latest) + ")");
  }
  for (const Migration& migration : MigrationsOf(engine())) {
    if (migration.version <= version || migration.version > goal) continue;
    auto status = RunOnWriter([&](Connection& c) -> api::Status {
      // Re-read inside the write lock: another process may have migrated.
      auto now_version = UserVersion(c);
      if (!now_version.ok()) return now_version.status();
      if (*now_version >= migration.version) return api::Status::Ok();
      if (auto s = c.ExecScript(migration.sql); !s.ok()) return s;
      if (migration.backfill) {
        if (auto s = migration.backfill(c); !s.ok()) return s;
      }
      if (!migration.sql_after.empty()) {
        if (auto s = c.ExecScript(migration.sql_after); !s.ok()) return s;
      }
      auto insert = c.Prepare(
          "INSERT INTO schema_migrations (version, name, applied_at_utc) VALUES (?1, ?2, ?3)");
      if (!insert.ok()) return insert.status();
      insert->Bind(1, migration.version).Bind(2, migration.name).Bind(3, api::FormatUtc(Now()));
      if (auto s = insert->Run(); !s.ok()) return s;
      if (c.engine() == Engine::kPostgres) return api::Status::Ok();  // the row is the version
      return c.ExecScript("PRAGMA user_version = " + std::to_string(migration.version));
    });
    if (!status.ok()) {
      return api::Status(status.code(), "migration " + std::to_string(migration.version) + " (" +
                                            migration.name + "): " + status.message());
    }
  }
  return api::Status::Ok();
}

api::Status Database::RunTransaction(bool write,
                                     const std::function<api::Status(Connection&)>& fn) {
  if (writer_owner_.load() == std::this_thread::get_id()) return fn(*writer_);
  if (!write && tls_reader_owner == this) return fn(*tls_reader);
  return write ? RunOnWriter(fn) : RunOnReader(fn);
}

api::Status Database::RunOnWriter(const std::function<api::Status(Connection&)>& fn) {
  std::vector<std::function<void()>> committed;
  api::Status result = [&] {
    std::lock_guard lock(writer_mutex_);
    return RunOnWriterLocked(fn, committed);
  }();
  for (auto& callback : committed) callback();
  return result;
}

api::Status Database::RunOnWriterLocked(const std::function<api::Status(Connection&)>& fn,
                                        std::vector<std::function<void()>>& committed) {
  const auto deadline = Clock::now() + options_.retry_budget;
  auto delay = std::chrono::milliseconds(1);
  int unique_retries = 0;
  while (true) {
    writer_->ClearBusy();
    after_commit_.clear();
    api::Status status = writer_->EnsureOpen();
    // PostgreSQL: SERIALIZABLE, so two servers writing at once cannot both
    // read the same "next version" (one is refused with a serialization
    // failure and retried here, like SQLite's busy).
    if (status.ok()) {
      status = writer_->ExecScript(engine() == Engine::kPostgres
                                       ? "BEGIN ISOLATION LEVEL SERIALIZABLE"
                                       : "BEGIN IMMEDIATE");
    }
    if (status.ok()) {
      writer_owner_.store(std::this_thread::get_id());
      try {
        status = fn(*writer_);
      } catch (const std::exception& e) {
        status =
            api::Status::Internal(std::string("exception in a write transaction: ") + e.what());
      }
      writer_owner_.store(std::thread::id());
      if (status.ok()) status = writer_->ExecScript("COMMIT");
      if (!writer_->autocommit()) (void)writer_->ExecScript("ROLLBACK");
    }
    if (status.ok()) {
      committed.swap(after_commit_);
      return status;
    }
    after_commit_.clear();
    // Two servers that both read "next version is 7" and both insert it:
    // PostgreSQL may refuse the second with a unique violation rather than
    // a serialization failure. Run it again on a fresh snapshot; a real
    // duplicate repeats every time and is returned after a few tries.
    const bool raced_on_a_key = status.code() == api::ErrorCode::kAlreadyExists &&
                                writer_->unique_conflict_seen() && ++unique_retries <= 10;
    if (!writer_->busy_seen() && !raced_on_a_key) return status;
    if (Clock::now() >= deadline) {
      return api::Status::Unavailable("database stayed busy for " +
                                      std::to_string(options_.retry_budget.count()) +
                                      " ms; retry later");
    }
    // A random part of the back-off, so that writers which collided do not
    // collide again in step (servers on one PostgreSQL database).
    const std::int64_t delay_us = std::chrono::microseconds(delay).count();
    std::this_thread::sleep_for(std::chrono::microseconds(
        std::uniform_int_distribution<std::int64_t>(delay_us / 2, delay_us)(jitter_)));
    delay = std::min(delay * 2, std::chrono::milliseconds(50));
  }
}

void Database::AfterCommit(std::function<void()> fn) {
  if (writer_owner_.load() == std::this_thread::get_id()) {
    after_commit_.push_back(std::move(fn));
  } else {
    fn();
  }
}

void Database::ApprovalsChanged() {
  AfterCommit([this] { approvals_version_.fetch_add(1); });
}

void Database::SetParameterSetListener(ParameterSetListener listener) {
  std::lock_guard lock(listener_mutex_);
  parameter_set_listener_ = std::move(listener);
}

void Database::CallParameterSetListener(const ParameterSetStored& event) {
  // Called under the lock, so that once SetParameterSetListener has replaced
  // a listener no thread (the writer's, or the notification thread) is still
  // inside the old one, whose owner may be going away.
  std::lock_guard lock(listener_mutex_);
  if (parameter_set_listener_) parameter_set_listener_(event);
}

api::Status Database::NotifyParameterSetStored(const ParameterSetStored& event) {
  if (engine() == Engine::kPostgres && writer_owner_.load() == std::this_thread::get_id()) {
    auto notify = writer_->Prepare("SELECT pg_notify('fesbench_parameter_sets', ?1)");
    if (!notify.ok()) return notify.status();
    notify->Bind(1, instance_id_ + " " + std::to_string(event.id) + " " +
                        std::to_string(event.subject_id) + " " + std::to_string(event.leg_id) +
                        (event.approval ? " 1" : " 0"));
    if (auto s = notify->Run(); !s.ok()) return s;
  }
  AfterCommit([this, event] { CallParameterSetListener(event); });
  return api::Status::Ok();
}

api::Status Database::RunOnReader(const std::function<api::Status(Connection&)>& fn) {
  Connection* reader = nullptr;
  {
    std::unique_lock lock(readers_mutex_);
    reader_freed_.wait(lock, [&] { return !free_readers_.empty(); });
    reader = free_readers_.back();
    free_readers_.pop_back();
  }
  const auto deadline = Clock::now() + options_.retry_budget;
  auto delay = std::chrono::milliseconds(1);
  api::Status status;
  while (true) {
    reader->ClearBusy();
    status = reader->EnsureOpen();
    if (status.ok()) {
      status = reader->ExecScript(engine() == Engine::kPostgres
                                      ? "BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY"
                                      : "BEGIN");
    }
    if (status.ok()) {
      tls_reader_owner = this;
      tls_reader = reader;
      try {
        status = fn(*reader);
      } catch (const std::exception& e) {
        status = api::Status::Internal(std::string("exception in a read transaction: ") + e.what());
      }
      tls_reader_owner = nullptr;
      tls_reader = nullptr;
      if (!reader->autocommit()) {
        api::Status end = reader->ExecScript("COMMIT");
        if (!reader->autocommit()) (void)reader->ExecScript("ROLLBACK");
        if (status.ok()) status = end;
      }
    }
    if (status.ok() || !reader->busy_seen()) break;
    if (Clock::now() >= deadline) {
      status = api::Status::Unavailable("database stayed busy for " +
                                        std::to_string(options_.retry_budget.count()) +
                                        " ms; retry later");
      break;
    }
    std::this_thread::sleep_for(delay);
    delay = std::min(delay * 2, std::chrono::milliseconds(50));
  }
  {
    std::lock_guard lock(readers_mutex_);
    free_readers_.push_back(reader);
  }
  reader_freed_.notify_one();
  return status;
}

api::Status Database::CheckIntegrity() {
  if (engine() == Engine::kPostgres) {  // the server checks its own pages
    return RunOnReader([](Connection& c) { return c.QueryText("SELECT 1").status(); });
  }
  return RunOnReader([&](Connection& c) -> api::Status {
    auto problems = IntegrityProblems(c, 20);
    if (!problems.ok()) return CheckedOpenStep(problems.status(), options_.path);
    if (problems->empty()) return api::Status::Ok();
    std::string detail = "integrity_check: ";
    for (std::size_t i = 0; i < problems->size(); ++i) {
      detail += (i == 0 ? "" : "; ") + (*problems)[i];
    }
    return CorruptStatus(options_.path, detail);
  });
}

api::Result<int> Database::SchemaVersion() {
  return Read([](Connection& c) { return UserVersion(c); });
}

api::Status Database::Backup(const std::string& destination_path) {
  if (engine() == Engine::kPostgres) return PostgresOnly("the online backup");
  namespace fs = std::filesystem;
  const std::string temporary = destination_path + ".partial-" + std::to_string(::getpid());
  std::error_code ignored;
  fs::remove(temporary, ignored);
  api::Status status;
  if (auto made = CreatePrivateFile(temporary); !made.ok()) return made;
  {
    auto destination = SqliteConnection::Open(
        temporary, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX,
        static_cast<int>(options_.busy_timeout.count()));
    if (!destination.ok()) return destination.status();
    // A reader connection is the source: the copy is one read transaction
    // (a WAL snapshot), so writers keep committing while it runs.
    Connection* reader = nullptr;
    {
      std::unique_lock lock(readers_mutex_);
      reader_freed_.wait(lock, [&] { return !free_readers_.empty(); });
      reader = free_readers_.back();
      free_readers_.pop_back();
    }
    status = CopyDatabase(static_cast<SqliteConnection&>(*reader), **destination, Clock::now() + options_.retry_budget);
    {
      std::lock_guard lock(readers_mutex_);
      free_readers_.push_back(reader);
    }
    reader_freed_.notify_one();
  }
  return FinishBackup(status, temporary, destination_path);
}

api::Status Database::RestoreFrom(const std::string& backup_path) {
  if (engine() == Engine::kPostgres) return PostgresOnly("restoring from a backup file");
  if (!std::filesystem::exists(backup_path)) {
    return api::Status::NotFound("backup file '" + backup_path + "' does not exist");
  }
  auto source = SqliteConnection::Open(backup_path, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX,
                                 static_cast<int>(options_.busy_timeout.count()));
  if (!source.ok()) return CheckedOpenStep(source.status(), backup_path);
  auto problems = IntegrityProblems(**source, 5);
  if (!problems.ok()) return CheckedOpenStep(problems.status(), backup_path);
  if (!problems->empty())
    return CorruptStatus(backup_path, "integrity_check: " + problems->front());
  auto version = UserVersion(**source);
  if (!version.ok()) return version.status();
  if (*version > LatestSchemaVersion()) {
    return api::Status::FailedPrecondition("backup schema version " + std::to_string(*version) +
                                           " is newer than this software's");
  }
  {
    std::lock_guard lock(writer_mutex_);
    auto status = CopyDatabase(**source, static_cast<SqliteConnection&>(*writer_), Clock::now() + options_.retry_budget);
    if (!status.ok()) return status;
    auto mode = writer_->QueryText("PRAGMA journal_mode = WAL");
    approvals_version_.fetch_add(1);  // whatever was copied, the approvals changed
    if (!mode.ok()) return mode.status();
  }
  return Migrate(std::nullopt);
}

api::Result<int> SqliteFileSchemaVersion(const std::string& path) {
  if (!std::filesystem::exists(path)) {
    return api::Status::NotFound("database file '" + path + "' does not exist");
  }
  auto source = SqliteConnection::Open(path, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX, 2000);
  if (!source.ok()) return CheckedOpenStep(source.status(), path);
  auto version = UserVersion(**source);
  if (!version.ok()) return CheckedOpenStep(version.status(), path);
  return *version;
}

api::Status BackupSqliteFile(const std::string& path, const std::string& destination_path) {
  namespace fs = std::filesystem;
  if (!fs::exists(path)) return api::Status::NotFound("database file '" + path + "' does not exist");
  const std::string temporary = destination_path + ".partial-" + std::to_string(::getpid());
  std::error_code ignored;
  fs::remove(temporary, ignored);
  if (auto made = CreatePrivateFile(temporary); !made.ok()) return made;
  api::Status status;
  {
    auto source = SqliteConnection::Open(path, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX, 2000);
    auto destination = SqliteConnection::Open(
        temporary, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, 2000);
    if (!source.ok()) {
      status = CheckedOpenStep(source.status(), path);
    } else if (!destination.ok()) {
      status = destination.status();
    } else {
      status = CopyDatabase(**source, **destination, Clock::now() + std::chrono::seconds(60));
      if (status.ok()) {
        auto problems = IntegrityProblems(**destination, 5);
        if (!problems.ok()) {
          status = problems.status();
        } else if (!problems->empty()) {
          status = CorruptStatus(temporary, "integrity_check: " + problems->front());
        }
      }
    }
  }
  return FinishBackup(status, temporary, destination_path);
}

}  // namespace fesbench::storage
