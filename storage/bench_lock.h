#pragma once

/// @file
/// One server per bench on a shared PostgreSQL database (docs/SAFETY.md,
/// "One server per bench"): a session advisory lock on the bench id, held by
/// a connection of its own, and watched by a thread for as long as the
/// server may run anything. PostgreSQL frees a session lock when its
/// connection ends (a restart, a failover, an idle-session killer,
/// pg_terminate_backend), so the watcher waits on that connection's socket
/// (a closed connection is seen at once) and checks every `check_interval`
/// that the lock is still held; a check left unanswered for
/// `answer_timeout` counts as a loss too. Once lost, it tries every
/// `check_interval` to take the lock back on a new connection: it is
/// regained, or found held by another session (another server: the end
/// for this one), or the database cannot be reached yet (it tries again).
/// Each change of state goes to the listener, which storage leaves to the
/// server to act on (the server stops stimulation and refuses runs).

#include <sys/types.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>

#include "api/status.h"

struct pg_conn;

namespace fesbench::storage {

enum class BenchLockState {
  kHeld,           ///< this server holds the bench.
  kLost,           ///< the lock's connection ended; trying to take it back.
  kHeldElsewhere,  ///< another session holds the bench now: stop serving it.
};
std::string_view BenchLockStateName(BenchLockState state);

struct BenchLockEvent {
  BenchLockState state = BenchLockState::kHeld;
  std::string bench_id;
  std::string detail;  ///< why it was lost, how it was regained, or who holds it.
};
/// Runs on the watcher thread; it may block (the watch waits for it).
using BenchLockListener = std::function<void(const BenchLockEvent&)>;

struct BenchLockOptions {
  std::string url;       ///< the database's libpq URL.
  std::string bench_id;  ///< the bench this server owns.
  /// Between two checks that the lock is held; also between two tries to
  /// take a lost lock back.
  std::chrono::milliseconds check_interval{250};
  /// A check unanswered this long counts as a lost lock (the connection may
  /// be gone without the socket saying so, e.g. a network partition).
  std::chrono::milliseconds answer_timeout{2000};
};

class PostgresBenchLock {
 public:
  /// Connects, takes the bench's lock and starts the watcher.
  /// kFailedPrecondition naming the bench when another session holds it;
  /// kUnavailable when the database cannot be reached.
  static api::Result<std::unique_ptr<PostgresBenchLock>> Acquire(BenchLockOptions options);
  /// Stops the watcher and frees the bench at once (without waiting for the
  /// server to notice the closed connection).
  ~PostgresBenchLock();
  PostgresBenchLock(const PostgresBenchLock&) = delete;
  PostgresBenchLock& operator=(const PostgresBenchLock&) = delete;

  /// Replaces the listener; when the lock is not held now, the new listener
  /// is told the current state at once. When it returns, no thread is inside
  /// the listener it replaced. Empty = none.
  void SetListener(BenchLockListener listener);
  BenchLockState state() const { return state_.load(); }

  /// The application_name of the lock's connection, so that an operator
  /// (and a test) finds it in pg_stat_activity: "fesbench bench lock <id>".
  static std::string ApplicationName(std::string_view bench_id);

 private:
  explicit PostgresBenchLock(BenchLockOptions options);
  void Loop();
  // Waits on the lock's connection for up to one check interval, then checks
  // the lock; false with `why` when it is lost.
  bool StillHeld(std::string& why);
  // One try to take the lock back (state kLost); true when the watch ends.
  bool TryTakeBack();
  // Sleeps `duration` unless stopped; true when stopped.
  bool SleepUnlessStopped(std::chrono::milliseconds duration);
  void Report(BenchLockState state, std::string detail);

  BenchLockOptions options_;
  pg_conn* conn_ = nullptr;   // the lock's connection (the watcher's, once started)
  int lost_backend_pid_ = 0;  // the server process of the connection that was lost
  std::atomic<BenchLockState> state_{BenchLockState::kHeld};
  std::atomic<bool> stop_{false};
  int wake_[2] = {-1, -1};     // a pipe: the destructor wakes the watcher through it
  std::mutex listener_mutex_;  // guards listener_ and last_ and serialises the calls
  BenchLockListener listener_;
  BenchLockEvent last_;
  std::thread watcher_;
};

}  // namespace fesbench::storage
