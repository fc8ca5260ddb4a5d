#pragma once

/// @file
/// One server per SQLite file (docs/SAFETY.md, "One server per bench"): an
/// exclusive flock on `<database>.lock` beside the file, held for as long
/// as the Database is open. The holder's pid is written into the lock file,
/// so a second server is refused naming it. The kernel frees the lock when
/// its holder exits, also after SIGKILL or a crash; the file itself stays.

#include <sys/types.h>

#include <memory>
#include <string>

#include "api/status.h"

namespace fesbench::storage {

class DatabaseFileLock {
 public:
  /// Takes the lock of `database_path` (its file `database_path` + ".lock",
  /// created 0600, opened O_CLOEXEC so no child program inherits it).
  /// kFailedPrecondition naming the database file, the lock file and the
  /// holder's pid when another process (or another open Database in this
  /// one) holds it; kUnavailable when the lock file cannot be made.
  static api::Result<std::unique_ptr<DatabaseFileLock>> Acquire(const std::string& database_path);
  /// Frees the lock (the lock file stays: removing it would let a third
  /// server lock a new file while a second still waits on the old one).
  ~DatabaseFileLock();
  DatabaseFileLock(const DatabaseFileLock&) = delete;
  DatabaseFileLock& operator=(const DatabaseFileLock&) = delete;

  /// `<database>.lock`.
  static std::string LockPathOf(const std::string& database_path);
  /// The pid written in the lock file at `lock_path`, or 0 when there is none.
  static pid_t HolderOf(const std::string& lock_path);

 private:
  explicit DatabaseFileLock(int fd) : fd_(fd) {}
  int fd_;
  bool held_ = false;  // the flock is ours (a refused Acquire leaves the file alone)
};

}  // namespace fesbench::storage
