#include "storage/bench_lock.h"

#include <fcntl.h>
#include <libpq-fe.h>
#include <poll.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>

#include "storage/postgres_connection.h"

namespace fesbench::storage {
namespace {

using Clock = std::chrono::steady_clock;

// The lock's key: one bigint per bench id (unchanged since benches first shared a database).
constexpr const char* kTryLock = "SELECT pg_try_advisory_lock(hashtext('fesbench bench ' || $1))";
// Still held by this session? The lock connection holds no other lock.
constexpr const char* kCheck =
    "SELECT count(*) FROM pg_locks WHERE locktype = 'advisory' AND granted"
    " AND pid = pg_backend_pid()";
// Who holds the bench's key in this database (pg_locks splits a bigint key
// into classid, the high half, and objid, the low half).
constexpr const char* kHolder =
    "WITH k AS (SELECT hashtext('fesbench bench ' || $1)::bigint AS key)"
    " SELECT l.pid, COALESCE(a.application_name, ''), COALESCE(host(a.client_addr), 'local')"
    " FROM pg_locks l CROSS JOIN k LEFT JOIN pg_stat_activity a ON a.pid = l.pid"
    " WHERE l.locktype = 'advisory' AND l.granted AND l.objsubid = 1"
    " AND l.database = (SELECT oid FROM pg_database WHERE datname = current_database())"
    " AND l.classid = ((k.key >> 32) & 4294967295)::oid AND l.objid = (k.key & 4294967295)::oid";

void IgnoreNotice(void*, const char*) {}

std::string Trimmed(const char* text) {
  std::string s = text != nullptr ? text : "";
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  return s;
}

// A connection for the lock, named in pg_stat_activity; null (with `error`)
// when the database cannot be reached.
PGconn* Connect(const BenchLockOptions& options, std::string& error) {
  const std::string name = PostgresBenchLock::ApplicationName(options.bench_id);
  // Keywords after dbname win over the URL's own (expand_dbname), those
  // before it give way: the URL may set its own connect_timeout.
  const char* keys[] = {"connect_timeout", "dbname", "application_name", nullptr};
  const char* values[] = {"5", options.url.c_str(), name.c_str(), nullptr};
  PGconn* conn = PQconnectdbParams(keys, values, /*expand_dbname=*/1);
  if (conn == nullptr || PQstatus(conn) != CONNECTION_OK) {
    error = conn != nullptr ? Trimmed(PQerrorMessage(conn)) : "out of memory";
    PQfinish(conn);
    return nullptr;
  }
  PQsetNoticeProcessor(conn, IgnoreNotice, nullptr);
  return conn;
}

// One row, one column of `sql` with the bench id as $1, as text.
api::Result<std::string> QueryOne(PGconn* conn, const char* sql, const std::string& bench_id) {
  const char* values[] = {bench_id.c_str()};
  PGresult* result = PQexecParams(conn, sql, 1, nullptr, values, nullptr, nullptr, 0);
  const bool ok = PQresultStatus(result) == PGRES_TUPLES_OK && PQntuples(result) == 1;
  std::string text = ok ? PQgetvalue(result, 0, 0) : "";
  const std::string error = Trimmed(PQerrorMessage(conn));
  PQclear(result);
  if (!ok) return api::Status::Unavailable(error);
  return text;
}

// "pid 1234, application 'fesbench bench lock knee-a', from 10.0.0.7", or
// "an unknown session" when it cannot tell.
std::string HolderText(PGconn* conn, const std::string& bench_id, int* holder_pid) {
  const char* values[] = {bench_id.c_str()};
  PGresult* result = PQexecParams(conn, kHolder, 1, nullptr, values, nullptr, nullptr, 0);
  std::string text = "an unknown session";
  if (PQresultStatus(result) == PGRES_TUPLES_OK && PQntuples(result) >= 1) {
    *holder_pid = std::atoi(PQgetvalue(result, 0, 0));
    text = "the session of pid " + std::string(PQgetvalue(result, 0, 0)) + ", application '" +
           PQgetvalue(result, 0, 1) + "', from " + PQgetvalue(result, 0, 2);
  }
  PQclear(result);
  return text;
}

}  // namespace

std::string_view BenchLockStateName(BenchLockState state) {
  switch (state) {
    case BenchLockState::kHeld:
      return "held";
    case BenchLockState::kLost:
      return "lost";
    case BenchLockState::kHeldElsewhere:
      return "held elsewhere";
  }
  return "unknown";
}

std::string PostgresBenchLock::ApplicationName(std::string_view bench_id) {
  // PostgreSQL keeps the first 63 bytes.
  return ("fesbench bench lock " + std::string(bench_id)).substr(0, 63);
}

PostgresBenchLock::PostgresBenchLock(BenchLockOptions options) : options_(std::move(options)) {}

api::Result<std::unique_ptr<PostgresBenchLock>> PostgresBenchLock::Acquire(
    BenchLockOptions options) {
  std::unique_ptr<PostgresBenchLock> lock(new PostgresBenchLock(std::move(options)));
  const BenchLockOptions& o = lock->options_;
  std::string error;
  lock->conn_ = Connect(o, error);
  if (lock->conn_ == nullptr) {
    return api::Status::Unavailable("cannot connect to PostgreSQL at " + RedactedUrl(o.url) +
                                    " for the bench lock: " + error);
  }
  auto taken = QueryOne(lock->conn_, kTryLock, o.bench_id);
  if (!taken.ok()) return taken.status();
  if (*taken != "t") {
    int holder = 0;
    return api::Status::FailedPrecondition(
        "bench '" + o.bench_id +
        "' is already served by another fesbench-server on this database (" +
        HolderText(lock->conn_, o.bench_id, &holder) + "); give each server its own --bench-id");
  }
  if (::pipe2(lock->wake_, O_CLOEXEC | O_NONBLOCK) != 0) {
    return api::Status::Unavailable("cannot create the bench lock's wake-up pipe");
  }
  lock->last_ = {BenchLockState::kHeld, o.bench_id, "taken at start"};
  PostgresBenchLock* self = lock.get();
  lock->watcher_ = std::thread([self] { self->Loop(); });
  return lock;
}

PostgresBenchLock::~PostgresBenchLock() {
  stop_ = true;
  if (wake_[1] >= 0) (void)::write(wake_[1], "x", 1);
  if (watcher_.joinable()) watcher_.join();
  if (conn_ != nullptr) {
    PQclear(PQexec(conn_, "SELECT pg_advisory_unlock_all()"));
    PQfinish(conn_);
  }
  for (int fd : wake_) {
    if (fd >= 0) ::close(fd);
  }
}

void PostgresBenchLock::SetListener(BenchLockListener listener) {
  std::lock_guard lock(listener_mutex_);
  listener_ = std::move(listener);
  if (listener_ && last_.state != BenchLockState::kHeld) listener_(last_);
}

void PostgresBenchLock::Report(BenchLockState state, std::string detail) {
  state_ = state;
  std::lock_guard lock(listener_mutex_);
  last_ = {state, options_.bench_id, std::move(detail)};
  if (listener_) listener_(last_);
}

void PostgresBenchLock::Loop() {
  while (!stop_) {
    if (state_ == BenchLockState::kHeld) {
      std::string why;
      if (StillHeld(why) || stop_) continue;
      lost_backend_pid_ = PQbackendPID(conn_);
      PQfinish(conn_);
      conn_ = nullptr;
      Report(BenchLockState::kLost, why);
      continue;
    }
    if (SleepUnlessStopped(options_.check_interval) || TryTakeBack()) return;
  }
}

bool PostgresBenchLock::StillHeld(std::string& why) {
  pollfd waiting[2] = {{PQsocket(conn_), POLLIN, 0}, {wake_[0], POLLIN, 0}};
  const int ready = ::poll(waiting, 2, static_cast<int>(options_.check_interval.count()));
  if (stop_) return true;
  if (ready < 0) return errno == EINTR;
  if (ready > 0) {
    // An idle connection has nothing to say, unless the server ends it
    // ("terminating connection due to administrator command") or closes it.
    if (PQconsumeInput(conn_) == 0 || PQstatus(conn_) != CONNECTION_OK) {
      why = "the connection holding the bench lock was closed: " + Trimmed(PQerrorMessage(conn_));
      return false;
    }
    while (PGresult* stray = PQgetResult(conn_)) PQclear(stray);
    return true;
  }
  if (PQsendQuery(conn_, kCheck) == 0) {
    why = "the connection holding the bench lock failed: " + Trimmed(PQerrorMessage(conn_));
    return false;
  }
  const auto deadline = Clock::now() + options_.answer_timeout;
  while (PQisBusy(conn_) != 0) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) {
      why = "the connection holding the bench lock did not answer within " +
            std::to_string(options_.answer_timeout.count()) + " ms";
      return false;
    }
    pollfd answer{PQsocket(conn_), POLLIN, 0};
    if (::poll(&answer, 1, static_cast<int>(left)) < 0 && errno != EINTR) {
      why = "waiting on the connection holding the bench lock failed";
      return false;
    }
    if (PQconsumeInput(conn_) == 0) {
      why = "the connection holding the bench lock was closed: " + Trimmed(PQerrorMessage(conn_));
      return false;
    }
  }
  bool held = false;
  std::string error;
  while (PGresult* result = PQgetResult(conn_)) {
    if (PQresultStatus(result) == PGRES_TUPLES_OK && PQntuples(result) == 1) {
      held = std::atoi(PQgetvalue(result, 0, 0)) >= 1;
    } else {
      error = Trimmed(PQresultErrorMessage(result));
    }
    PQclear(result);
  }
  if (!error.empty() || PQstatus(conn_) != CONNECTION_OK) {
    why = "checking the bench lock failed: " +
          (error.empty() ? Trimmed(PQerrorMessage(conn_)) : error);
    return false;
  }
  if (!held) why = "the bench lock is no longer held by this server's connection";
  return held;
}

bool PostgresBenchLock::TryTakeBack() {
  std::string error;
  PGconn* conn = Connect(options_, error);
  if (conn == nullptr) return false;  // the database is not back yet: try again
  auto taken = QueryOne(conn, kTryLock, options_.bench_id);
  if (taken.ok() && *taken == "t") {
    conn_ = conn;
    Report(BenchLockState::kHeld, "taken back on a new connection");
    return false;
  }
  int holder = 0;
  const std::string who = taken.ok() ? HolderText(conn, options_.bench_id, &holder) : "";
  PQfinish(conn);
  // Not taken: a failed query (try again), or the server has not yet ended
  // the lost connection's session, which still holds it (wait for it).
  if (!taken.ok() || holder == 0 || holder == lost_backend_pid_) return false;
  Report(BenchLockState::kHeldElsewhere, "bench '" + options_.bench_id + "' is now held by " + who);
  return true;
}

bool PostgresBenchLock::SleepUnlessStopped(std::chrono::milliseconds duration) {
  pollfd waiting{wake_[0], POLLIN, 0};
  (void)::poll(&waiting, 1, static_cast<int>(duration.count()));
  return stop_;
}

}  // namespace fesbench::storage
