// One server per database file and per bench, and private files
// (docs/SAFETY.md, "One server per bench" and "Files"): the SQLite lock file,
// the PostgreSQL bench lock's watch (a killed lock connection is reported,
// taken back, or found taken by another session), and the modes of what
// storage creates under a permissive umask.

#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <string>
#include <vector>

#include "storage/bench_lock.h"
#include "storage/database.h"
#include "storage/file_lock.h"
#include "storage/postgres_connection.h"
#include "storage/private_files.h"
#include "storage/subjects.h"
#include "storage_test_util.h"

namespace fesbench::storage {
namespace {

using testing::MakeTempDir;
using testing::PostgresStorageTest;
using testing::SqliteStorageTest;
using Clock = std::chrono::steady_clock;

mode_t ModeOf(const std::filesystem::path& path) {
  struct stat info {};
  EXPECT_EQ(::stat(path.c_str(), &info), 0) << path;
  return info.st_mode & 07777;
}

// Sets the umask for one scope.
class Umask {
 public:
  explicit Umask(mode_t mask) : old_(::umask(mask)) {}
  ~Umask() { ::umask(old_); }

 private:
  mode_t old_;
};

TEST_F(SqliteStorageTest, ASecondDatabaseOnTheFileIsRefusedNamingFileAndHolder) {
  auto second = Database::Open(Options());
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.status().code(), api::ErrorCode::kFailedPrecondition);
  const std::string& message = second.status().message();
  EXPECT_NE(message.find("'" + path_ + "'"), std::string::npos) << message;
  EXPECT_NE(message.find("pid " + std::to_string(::getpid())), std::string::npos) << message;
  EXPECT_NE(message.find(path_ + ".lock"), std::string::npos) << message;
  EXPECT_EQ(DatabaseFileLock::HolderOf(path_ + ".lock"), ::getpid());

  db_.reset();  // the file is free once its Database is closed
  auto reopened = Database::Open(Options());
  ASSERT_TRUE(reopened.ok()) << reopened.status().ToString();
  db_ = std::move(*reopened);
}

TEST_F(SqliteStorageTest, WithoutTheLockFileOptionTwoDatabasesShareTheFile) {
  DatabaseOptions unlocked = Options();
  unlocked.lock_file = false;
  auto second = Database::Open(unlocked);
  ASSERT_TRUE(second.ok()) << second.status().ToString();
  ASSERT_TRUE(SubjectRepository(**second).Create("L1", SubjectDetails{}).ok());
  auto seen = SubjectRepository(*db_).List();
  ASSERT_TRUE(seen.ok());
  EXPECT_EQ(seen->size(), 1u);
}

TEST(DatabaseFiles, AreTheOwnersOnlyUnderAPermissiveUmask) {
  const Umask permissive(022);
  const auto dir = MakeTempDir("modes");
  const std::string path = (dir / "fesbench.db").string();
  DatabaseOptions options;
  options.path = path;
  auto db = Database::Open(options);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  ASSERT_TRUE(SubjectRepository(**db).Create("M1", SubjectDetails{}).ok());
  EXPECT_EQ(ModeOf(path), 0600u);
  EXPECT_EQ(ModeOf(path + "-wal"), 0600u);
  EXPECT_EQ(ModeOf(path + "-shm"), 0600u);
  EXPECT_EQ(ModeOf(path + ".lock"), 0600u);
  EXPECT_TRUE((*db)->open_notes().empty());

  const std::string backup = (dir / "backup.db").string();
  ASSERT_TRUE((*db)->Backup(backup).ok());
  EXPECT_EQ(ModeOf(backup), 0600u);
  db->reset();
  std::filesystem::remove_all(dir);
}

TEST(DatabaseFiles, AnOlderDatabaseOpenToOthersIsNarrowedAndSaid) {
  const Umask permissive(022);
  const auto dir = MakeTempDir("narrow");
  const std::string path = (dir / "fesbench.db").string();
  DatabaseOptions options;
  options.path = path;
  ASSERT_TRUE(Database::Open(options).ok());
  ASSERT_EQ(::chmod(path.c_str(), 0644), 0);
  ASSERT_EQ(::chmod((path + ".lock").c_str(), 0644), 0);
  auto db = Database::Open(options);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  EXPECT_EQ(ModeOf(path), 0600u);
  EXPECT_EQ(ModeOf(path + ".lock"), 0600u);
  ASSERT_EQ((*db)->open_notes().size(), 1u);
  EXPECT_NE((*db)->open_notes()[0].find("'" + path + "' from mode 0644 to 0600"), std::string::npos)
      << (*db)->open_notes()[0];
  db->reset();
  std::filesystem::remove_all(dir);
}

TEST(PrivateFolders, NewOnesAre0700AndExistingOnesAreLeftAlone) {
  const Umask permissive(022);
  const auto dir = MakeTempDir("folders");
  ASSERT_EQ(::chmod(dir.c_str(), 0755), 0);
  ASSERT_TRUE(CreatePrivateFolders(dir / "a" / "b").ok());
  EXPECT_EQ(ModeOf(dir / "a"), 0700u);
  EXPECT_EQ(ModeOf(dir / "a" / "b"), 0700u);
  EXPECT_EQ(ModeOf(dir), 0755u);
  ASSERT_TRUE(CreatePrivateFolders(dir).ok());
  EXPECT_EQ(ModeOf(dir), 0755u);
  EXPECT_EQ(CreatePrivateFolders("/proc/fesbench-none").code(), api::ErrorCode::kUnavailable);
  std::filesystem::remove_all(dir);
}

// --- PostgreSQL: the bench lock's watch ------------------------------------------------

// The bench lock's events, as a test waits for them.
class Events {
 public:
  BenchLockListener Listener() {
    return [this](const BenchLockEvent& event) {
      std::lock_guard lock(mu_);
      events_.push_back(event);
      at_.push_back(Clock::now());
      cv_.notify_all();
    };
  }
  // The n-th event (0-based), waiting up to `timeout`; nullopt if none came.
  std::optional<BenchLockEvent> Wait(std::size_t n, std::chrono::seconds timeout,
                                     Clock::time_point* at = nullptr) {
    std::unique_lock lock(mu_);
    if (!cv_.wait_for(lock, timeout, [&] { return events_.size() > n; })) return std::nullopt;
    if (at != nullptr) *at = at_[n];
    return events_[n];
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  std::vector<BenchLockEvent> events_;
  std::vector<Clock::time_point> at_;
};

// Runs `sql` on a connection of its own; its first value.
std::string Query(const std::string& url, const std::string& sql) {
  auto conn = PostgresConnection::Open(url);
  if (!conn.ok()) return conn.status().ToString();
  auto value = (*conn)->QueryText(sql);
  return value.ok() ? *value : value.status().ToString();
}

std::string TerminateLockConnection(const std::string& url, const std::string& bench_id) {
  return Query(url,
               "SELECT count(pg_terminate_backend(pid)) FROM pg_stat_activity"
               " WHERE datname = current_database() AND application_name = '" +
                   PostgresBenchLock::ApplicationName(bench_id) + "'");
}

TEST_F(PostgresStorageTest, AKilledLockConnectionIsReportedAndTheLockTakenBack) {
  Events events;
  db_->SetBenchLockListener(events.Listener());
  EXPECT_FALSE(events.Wait(0, std::chrono::seconds(0)));  // held: nothing to say

  const auto killed_at = Clock::now();
  ASSERT_EQ(TerminateLockConnection(path_, "bench-a"), "1");
  Clock::time_point lost_at, back_at;
  auto lost = events.Wait(0, std::chrono::seconds(10), &lost_at);
  ASSERT_TRUE(lost);
  EXPECT_EQ(lost->state, BenchLockState::kLost);
  EXPECT_EQ(lost->bench_id, "bench-a");
  EXPECT_NE(lost->detail.find("closed"), std::string::npos) << lost->detail;
  auto back = events.Wait(1, std::chrono::seconds(10), &back_at);
  ASSERT_TRUE(back);
  EXPECT_EQ(back->state, BenchLockState::kHeld) << back->detail;
  std::printf(
      "bench lock: connection killed → lost reported in %.1f ms, taken back after %.1f ms\n",
      std::chrono::duration<double, std::milli>(lost_at - killed_at).count(),
      std::chrono::duration<double, std::milli>(back_at - killed_at).count());

  // Held again, on the new connection: a second server is still refused.
  auto second = Database::Open(Options());
  ASSERT_FALSE(second.ok());
  EXPECT_NE(second.status().message().find("bench 'bench-a'"), std::string::npos)
      << second.status().message();
  EXPECT_NE(second.status().message().find(PostgresBenchLock::ApplicationName("bench-a")),
            std::string::npos)
      << second.status().message();
}

TEST_F(PostgresStorageTest, ALostLockTakenByAnotherSessionEndsTheWatch) {
  // This Database waits 3 s before it tries to take the lock back, so the
  // competitor below gets it first.
  db_.reset();
  DatabaseOptions slow = Options();
  slow.bench_lock_check_interval = std::chrono::milliseconds(3000);
  auto db = Database::Open(slow);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  Events events;
  (*db)->SetBenchLockListener(events.Listener());

  ASSERT_EQ(TerminateLockConnection(path_, "bench-a"), "1");
  auto lost = events.Wait(0, std::chrono::seconds(10));
  ASSERT_TRUE(lost);
  EXPECT_EQ(lost->state, BenchLockState::kLost);
  DatabaseOptions competitor = Options();
  competitor.bench_lock_check_interval = std::chrono::milliseconds(250);
  auto other = Database::Open(competitor);
  ASSERT_TRUE(other.ok()) << other.status().ToString();

  auto taken = events.Wait(1, std::chrono::seconds(15));
  ASSERT_TRUE(taken);
  EXPECT_EQ(taken->state, BenchLockState::kHeldElsewhere);
  EXPECT_NE(taken->detail.find("bench 'bench-a' is now held by"), std::string::npos)
      << taken->detail;
  EXPECT_NE(taken->detail.find(PostgresBenchLock::ApplicationName("bench-a")), std::string::npos)
      << taken->detail;

  // A listener set later is told at once.
  Events late;
  (*db)->SetBenchLockListener(late.Listener());
  auto told = late.Wait(0, std::chrono::seconds(0));
  ASSERT_TRUE(told);
  EXPECT_EQ(told->state, BenchLockState::kHeldElsewhere);
  (*db)->SetBenchLockListener({});
  db->reset();
}

}  // namespace
}  // namespace fesbench::storage
