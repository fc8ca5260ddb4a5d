#include "storage/file_lock.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include "storage/private_files.h"

namespace fesbench::storage {

std::string DatabaseFileLock::LockPathOf(const std::string& database_path) {
  return database_path + ".lock";
}

pid_t DatabaseFileLock::HolderOf(const std::string& lock_path) {
  const int fd = ::open(lock_path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return 0;
  char text[32] = {};
  const ssize_t n = ::pread(fd, text, sizeof text - 1, 0);
  ::close(fd);
  if (n <= 0) return 0;
  char* end = nullptr;
  const long pid = std::strtol(text, &end, 10);
  return pid > 0 && end != text ? static_cast<pid_t>(pid) : 0;
}

api::Result<std::unique_ptr<DatabaseFileLock>> DatabaseFileLock::Acquire(
    const std::string& database_path) {
  const std::string lock_path = LockPathOf(database_path);
  const int fd =
      ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, kPrivateFileMode);
  if (fd < 0) {
    return api::Status::Unavailable("cannot open the lock file '" + lock_path +
                                    "' of the database: " + std::strerror(errno));
  }
  std::unique_ptr<DatabaseFileLock> lock(new DatabaseFileLock(fd));
  int rc = 0;
  do {
    rc = ::flock(fd, LOCK_EX | LOCK_NB);
  } while (rc != 0 && errno == EINTR);
  if (rc != 0) {
    const int error = errno;
    if (error != EWOULDBLOCK) {
      return api::Status::Unavailable("cannot lock '" + lock_path + "': " + std::strerror(error));
    }
    const pid_t holder = HolderOf(lock_path);
    const std::string who = holder > 0 ? "pid " + std::to_string(holder) : "pid unknown";
    return api::Status::FailedPrecondition(
        "database file '" + database_path + "' is in use by another fesbench-server (" + who +
        ", lock file '" + lock_path +
        "'): one server per database file; stop that server first or give this one its own --db");
  }
  // Ours now: narrow a lock file left by an older version, record our pid.
  lock->held_ = true;
  (void)::fchmod(fd, kPrivateFileMode);
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd, 0) != 0 ||
      ::pwrite(fd, pid.data(), pid.size(), 0) != static_cast<ssize_t>(pid.size())) {
    return api::Status::Unavailable("cannot write the lock file '" + lock_path +
                                    "': " + std::strerror(errno));
  }
  return lock;
}

DatabaseFileLock::~DatabaseFileLock() {
  if (fd_ < 0) return;
  if (held_) (void)::ftruncate(fd_, 0);  // no stale pid for whoever reads it next
  ::close(fd_);                          // frees the flock
}

}  // namespace fesbench::storage
