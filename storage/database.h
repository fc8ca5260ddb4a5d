#pragma once

/// @file
/// The database (docs/ARCHITECTURE.md, storage), on either engine: an SQLite file (the
/// default) or a PostgreSQL server, chosen by DatabaseOptions::path. One
/// writer connection serialised by a mutex and a small pool of reader
/// connections. WAL lets readers proceed
/// while one transaction writes; a busy timeout plus a retry of the whole
/// transaction keep "database is locked" from ever reaching a caller (after
/// `retry_budget` of contention it becomes kUnavailable, retry may succeed).
///
/// Opening an SQLite file applies, in order: WAL journal, foreign keys, the synchronous
/// level, PRAGMA integrity_check (kDataLoss naming the file on any problem:
/// the database refuses to run on a corrupt file), then the pending numbered
/// migrations (storage/migrations.h), each in its own transaction. Opening
/// PostgreSQL connects the writer and readers and applies the pending
/// migrations under an advisory lock (one server migrates, the others wait).
/// Write transactions are SERIALIZABLE there and reads REPEATABLE READ (one
/// snapshot), and a serialization failure is retried like SQLite's busy.
///
/// One server per database file and per bench: an SQLite file is locked
/// (`<file>.lock`, storage/file_lock.h) before anything else touches it; on
/// PostgreSQL the bench's advisory lock is taken before migrating and
/// watched for as long as the Database is open (storage/bench_lock.h).
/// The files it creates are 0600 (storage/private_files.h).
///
/// IsPostgresUrl tells the two apart: postgresql:// or postgres://.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

#include "api/status.h"
#include "storage/bench_lock.h"
#include "storage/connection.h"
#include "api/time_utc.h"

namespace fesbench::storage {

/// PRAGMA synchronous. kFull (the default) fsyncs the WAL at every commit,
/// so a transaction acknowledged to a client survives power loss as well as
/// a process crash; kNormal survives process crashes only (see README).
enum class Synchronous { kNormal, kFull };

bool IsPostgresUrl(std::string_view location);

struct DatabaseOptions {
  /// The database file (created if missing), or a PostgreSQL URL
  /// (postgresql://user@host:port/database, libpq's URI form; the database
  /// must exist, its schema is migrated at open). Several servers may share
  /// one PostgreSQL database; an SQLite file belongs to one server.
  std::string path;
  Synchronous synchronous = Synchronous::kFull;
  int reader_count = 4;                           ///< reader connections, ≥ 1.
  std::chrono::milliseconds busy_timeout{2000};   ///< SQLite's own wait per attempt.
  std::chrono::milliseconds retry_budget{30000};  ///< total wait before kUnavailable.
  bool check_integrity = true;                    ///< PRAGMA integrity_check at open.
  /// Apply migrations up to this version only (tests of upgrades); nullopt
  /// applies all of them.
  std::optional<int> target_schema_version;
  /// The bench this process owns (one server per bench, docs/SAFETY.md): the runs and e-stop
  /// presses it records carry it, and it sees only its own when it looks for runs left
  /// unfinished or for a set latch. Rows from before benches had ids (the
  /// bench '') belong to every bench. On PostgreSQL a second process that
  /// opens the database for the same bench is refused.
  std::string bench_id;
  /// The clock of every *_utc column; outlives the database.
  api::Clock* clock = api::Clock::Real();
  /// SQLite: hold `<path>.lock` exclusively while open, so a second server
  /// (or a second Database in this process) on the file is refused
  /// (storage/file_lock.h). false only for tests that open one file twice
  /// in one process, as two benches would.
  bool lock_file = true;
  /// PostgreSQL: how often the bench lock is checked, and a lost one tried
  /// again (storage/bench_lock.h).
  std::chrono::milliseconds bench_lock_check_interval{250};
};

/// The schema version of the SQLite file at `path` (PRAGMA user_version),
/// read on a read-only connection without the file's lock, so also while a
/// server holds it. kNotFound when the file does not exist.
api::Result<int> SqliteFileSchemaVersion(const std::string& path);

/// Online backup of the SQLite file at `path` into `destination_path`
/// through SQLite's backup API, from a read-only connection that does not
/// take the file's lock: a running server keeps writing meanwhile and the
/// copy is one consistent snapshot (docs/ARCHITECTURE.md, "Backup"). The
/// copy is written to a temporary file made 0600, checked with
/// integrity_check, then renamed. kNotFound when the file does not exist.
api::Status BackupSqliteFile(const std::string& path, const std::string& destination_path);

class PostgresListener;
class PostgresBenchLock;
class DatabaseFileLock;

class Database {
 public:
  /// Opens (or creates) the database. Errors: kDataLoss for a file that is
  /// not a database or fails integrity_check; kFailedPrecondition for a
  /// schema newer than this software; kUnavailable when the file cannot be
  /// opened; kInvalidArgument for bad options.
  static api::Result<std::unique_ptr<Database>> Open(DatabaseOptions options);
  ~Database();
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;

  /// Runs `fn(Connection&)` in one write transaction (BEGIN IMMEDIATE …
  /// COMMIT) on the writer connection; rolls back when fn returns an error
  /// (Status, or a Result<T> without value). On SQLITE_BUSY the whole
  /// transaction is retried, so fn may run more than once: it must not have
  /// side effects outside the database. A Write (or Read) called from inside
  /// fn on the same thread joins the open transaction. Returns fn's result.
  template <typename F>
  auto Write(F&& fn) -> std::invoke_result_t<F, Connection&> {
    return Run(/*write=*/true, std::forward<F>(fn));
  }
  /// Runs `fn` in one read transaction (a consistent snapshot) on a pooled
  /// reader connection; inside a Write on this thread, on the writer.
  template <typename F>
  auto Read(F&& fn) -> std::invoke_result_t<F, Connection&> {
    return Run(/*write=*/false, std::forward<F>(fn));
  }

  /// Online backup through SQLite's backup API into `destination_path`
  /// (written to a temporary file, then renamed). Writers are not blocked:
  /// the copy is one consistent snapshot read from a reader connection.
  api::Status Backup(const std::string& destination_path);
  /// Replaces the whole content with that of the backup at `backup_path`,
  /// after checking the backup's integrity (kDataLoss if it is corrupt) and
  /// schema version; migrates it forward if it is older.
  api::Status RestoreFrom(const std::string& backup_path);

  /// PRAGMA integrity_check: OK, or kDataLoss listing the first problems.
  api::Status CheckIntegrity();
  /// The schema version in the file (PRAGMA user_version).
  api::Result<int> SchemaVersion();

  /// The time stamp for new rows, from options.clock.
  api::UtcTime Now() const;

  /// Runs `fn` once the current write transaction (the outermost one, on
  /// this thread) has committed; dropped if it rolls back. Outside a write
  /// transaction, runs it at once. The callbacks run on the writing thread
  /// after the writer is released, so they may read or write themselves.
  void AfterCommit(std::function<void()> fn);

  /// A stored parameter set (new sets as events, no polling).
  struct ParameterSetStored {
    std::int64_t id = 0;
    std::int64_t subject_id = 0;
    std::int64_t leg_id = 0;
    bool approval = false;  ///< the set was approved (ParameterSetRepository::Approve), not stored.
  };
  using ParameterSetListener = std::function<void(const ParameterSetStored&)>;
  /// Called after the commit of every stored parameter set, on the writing
  /// thread (ParameterSetRepository::Insert); on PostgreSQL also for the
  /// sets other servers store, on this database's notification thread
  /// (NOTIFY, delivered at their commit). Empty = none. Thread-safe: when it
  /// returns, no thread is inside the listener it replaced.
  void SetParameterSetListener(ParameterSetListener listener);
  /// Notifies the listener after the current transaction commits, and on
  /// PostgreSQL every other server's (a NOTIFY in the same transaction).
  api::Status NotifyParameterSetStored(const ParameterSetStored& event);
  /// The bench lock's changes of state (PostgreSQL, storage/bench_lock.h),
  /// on its watcher thread; told the current state at once when the lock is
  /// not held now. An SQLite file's lock cannot be lost: never called there.
  /// When it returns, no thread is inside the listener it replaced.
  void SetBenchLockListener(BenchLockListener listener);
  /// Approvals of parameter sets as a version number for caches of them: it
  /// grows after the commit of every approval made through this Database
  /// (ApprovalsChanged, inside the approving transaction) and after a
  /// restore. Other servers' approvals (PostgreSQL) do not move it, so a
  /// cache keyed on it is sound only where this Database is the only writer
  /// (only_writer()).
  std::uint64_t approvals_version() const { return approvals_version_.load(); }
  /// Counts one change of approvals once the current write transaction
  /// commits (at once outside one); nothing if it rolls back.
  void ApprovalsChanged();
  /// True for an SQLite file held under its lock (DatabaseOptions::lock_file):
  /// nothing but this Database writes to it.
  bool only_writer() const { return file_lock_ != nullptr; }
  /// What Open changed on its way, for the server to say: the files of the
  /// database that group or others could read, narrowed to 0600.
  const std::vector<std::string>& open_notes() const { return open_notes_; }

  const DatabaseOptions& options() const { return options_; }
  /// The engine behind options().path.
  Engine engine() const;

 private:
  explicit Database(DatabaseOptions options);
  api::Status Initialise();
  api::Status InitialisePostgres();
  api::Status Migrate(std::optional<int> target);
  api::Status RunTransaction(bool write, const std::function<api::Status(Connection&)>& fn);
  api::Status RunOnWriter(const std::function<api::Status(Connection&)>& fn);
  /// RunOnWriter with writer_mutex_ held; `committed` receives the
  /// AfterCommit callbacks of a committed transaction.
  api::Status RunOnWriterLocked(const std::function<api::Status(Connection&)>& fn,
                                std::vector<std::function<void()>>& committed);
  api::Status RunOnReader(const std::function<api::Status(Connection&)>& fn);

  template <typename F>
  auto Run(bool write, F&& fn) -> std::invoke_result_t<F, Connection&> {
    using R = std::invoke_result_t<F, Connection&>;
    if constexpr (std::is_same_v<R, api::Status>) {
      return RunTransaction(write, [&](Connection& c) { return fn(c); });
    } else {
      std::optional<R> out;
      api::Status status = RunTransaction(write, [&](Connection& c) {
        out.emplace(fn(c));
        return out->ok() ? api::Status::Ok() : out->status();
      });
      if (!status.ok()) return R(std::move(status));
      return std::move(*out);
    }
  }

  DatabaseOptions options_;
  std::unique_ptr<Connection> writer_;
  std::mutex writer_mutex_;
  std::minstd_rand jitter_{std::random_device{}()};  // back-off jitter, under writer_mutex_
  std::atomic<std::thread::id> writer_owner_{};      // the thread inside a write transaction
  std::vector<std::function<void()>> after_commit_;  // owned by the writer_owner_ thread
  std::atomic<std::uint64_t> approvals_version_{0};
  std::mutex listener_mutex_;                        // guards parameter_set_listener_
  ParameterSetListener parameter_set_listener_;

  api::Status MakePrivateFiles();

  std::unique_ptr<DatabaseFileLock> file_lock_;    // SQLite: one server per file
  std::unique_ptr<PostgresBenchLock> bench_lock_;  // PostgreSQL: one server per bench
  std::vector<std::string> open_notes_;
  // PostgreSQL: the sets other servers store (their NOTIFY payloads carry
  // the storing Database's instance id, so this one skips its own).
  std::string instance_id_;
  std::unique_ptr<PostgresListener> notifications_;
  void CallParameterSetListener(const ParameterSetStored& event);
  std::vector<std::unique_ptr<Connection>> readers_;
  std::vector<Connection*> free_readers_;
  std::mutex readers_mutex_;
  std::condition_variable reader_freed_;
};

}  // namespace fesbench::storage
