#include "storage/database.h"

#include <gtest/gtest.h>

#include <atomic>
#include <condition_variable>
#include <fstream>
#include <mutex>
#include <random>
#include <thread>
#include <vector>

#include "model/parameter_set.h"
#include "storage/audit_log.h"
#include "storage/estop_latch.h"
#include "storage/migrations.h"
#include "storage/parameter_sets.h"
#include "storage/sessions.h"
#include "storage/subjects.h"
#include "storage/users.h"
#include "storage_test_util.h"

namespace fesbench::storage {
namespace {

using testing::PostgresStorageTest;
using testing::SqliteStorageTest;
using testing::StorageTest;

TEST_F(SqliteStorageTest, OpensInWalWithForeignKeysAndFullSync) {
  auto pragmas = db_->Read([](Connection& c) -> api::Result<std::string> {
    auto mode = c.QueryText("PRAGMA journal_mode");
    auto fk = c.QueryText("PRAGMA foreign_keys");
    if (!mode.ok() || !fk.ok()) return api::Status::Internal("pragma failed");
    return *mode + "," + *fk;
  });
  ASSERT_TRUE(pragmas.ok()) << pragmas.status().ToString();
  EXPECT_EQ(*pragmas, "wal,1");
  auto sync = db_->Write([](Connection& c) { return c.QueryText("PRAGMA synchronous"); });
  ASSERT_TRUE(sync.ok());
  EXPECT_EQ(*sync, "2");  // FULL
  auto version = db_->SchemaVersion();
  ASSERT_TRUE(version.ok());
  EXPECT_EQ(*version, LatestSchemaVersion());
  EXPECT_EQ(LatestSchemaVersion(), 19);
  auto recorded = db_->Read([](Connection& c) {
    return c.QueryText("SELECT group_concat(version) FROM schema_migrations");
  });
  ASSERT_TRUE(recorded.ok());
  EXPECT_EQ(*recorded, "1,2,3,4,5,6,7,8,9,10,11,12,13,14,15,16,17,18,19");
}

TEST_P(StorageTest, ReopeningAppliesNothingTwice) {
  db_.reset();
  auto db = Database::Open(Options());
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  auto count = (*db)->Read(
      [](Connection& c) { return c.QueryText("SELECT count(*) FROM schema_migrations"); });
  ASSERT_TRUE(count.ok());
  const auto& applied = GetParam() == Engine::kPostgres ? PostgresMigrations() : AllMigrations();
  EXPECT_EQ(*count, std::to_string(applied.size()));
  auto version = (*db)->SchemaVersion();
  ASSERT_TRUE(version.ok());
  EXPECT_EQ(*version, LatestSchemaVersion());
}

TEST_F(SqliteStorageTest, MigrationFromVersionOneKeepsEveryRow) {
  db_.reset();
  std::filesystem::remove(path_);
  DatabaseOptions v1 = Options();
  v1.target_schema_version = 1;
  std::int64_t subject_id = 0;
  std::int64_t session_id = 0;
  std::int64_t user_id = 0;
  {
    auto db = Database::Open(v1);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    auto version = (*db)->SchemaVersion();
    ASSERT_TRUE(version.ok());
    EXPECT_EQ(*version, 1);
    // Tables of later migrations do not exist yet.
    auto tables = (*db)->Read([](Connection& c) {
      return c.QueryText("SELECT count(*) FROM sqlite_schema WHERE name = 'trials'");
    });
    ASSERT_TRUE(tables.ok());
    EXPECT_EQ(*tables, "0");

    // Rows as the version-1 schema had them (today's repositories write
    // columns of later migrations), a finished run among them.
    ASSERT_TRUE((*db)
                    ->Write([](Connection& c) {
                      return c.ExecScript(
                          "INSERT INTO subjects VALUES (1, 'P07', '2026-02-03T08:00:00.000000Z');"
                          "INSERT INTO subject_revisions (id, subject_id, revision, age_years, sex,"
                          " height_cm, corrects_id, reason, recorded_at_utc) VALUES"
                          " (1, 1, 1, 34, 'female', 168.5, NULL, '', '2026-02-03T08:00:00.000000Z'),"
                          " (2, 1, 2, 34, 'female', 169.0, 1, 'remeasured',"
                          " '2026-02-03T08:01:00.000000Z');"
                          "INSERT INTO legs VALUES (1, 1, 'left', '2026-02-03T08:00:00.000000Z');"
                          "INSERT INTO sessions VALUES (1, 1, 1, '2026-02-03T08:02:00.000000Z');"
                          "INSERT INTO session_revisions (id, session_id, revision, session_date,"
                          " accelerometer_placement, threshold_ma, max_tolerated_ma, notes,"
                          " corrects_id, reason, recorded_at_utc) VALUES (1, 1, 1, '2026-02-03',"
                          " 'lateral shank', 18.0, 55.0, 'first visit', NULL, '',"
                          " '2026-02-03T08:02:00.000000Z');"
                          "INSERT INTO runs (id, session_id, protocol_name, protocol_version,"
                          " parameters_json, created_at_utc) VALUES (1, 1, 'irc_ramp', '1', '{}',"
                          " '2026-02-03T08:03:00.000000Z');"
                          "INSERT INTO run_events (run_id, state, message, at_utc) VALUES"
                          " (1, 'queued', '', '2026-02-03T08:03:00.000000Z'),"
                          " (1, 'running', '', '2026-02-03T08:03:01.000000Z'),"
                          " (1, 'completed', '', '2026-02-03T08:03:09.000000Z');");
                    })
                    .ok());
    subject_id = 1;
    session_id = 1;
    auto user = UserRepository(**db).CreateUser("alice", Role::kClinician);
    ASSERT_TRUE(user.ok());
    user_id = user->id;
    ASSERT_TRUE(
        AuditLog(**db)
            .Append({user_id, "alice", "POST /api/v1/subjects", "subjects/1", "{code: P07}", "201"})
            .ok());
  }
  auto db = Database::Open(Options());
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  auto version = (*db)->SchemaVersion();
  ASSERT_TRUE(version.ok());
  EXPECT_EQ(*version, LatestSchemaVersion());

  auto subject = SubjectRepository(**db).Get(subject_id);
  ASSERT_TRUE(subject.ok());
  EXPECT_EQ(subject->code, "P07");
  EXPECT_EQ(subject->current.revision, 2);
  EXPECT_EQ(subject->current.details.height_cm, 169.0);
  EXPECT_EQ(subject->current.details.age_years, 34);
  auto revisions = SubjectRepository(**db).Revisions(subject_id);
  ASSERT_TRUE(revisions.ok());
  ASSERT_EQ(revisions->size(), 2u);
  EXPECT_EQ((*revisions)[0].details.height_cm, 168.5);
  auto session = SessionRepository(**db).Get(session_id);
  ASSERT_TRUE(session.ok());
  EXPECT_EQ(session->current.details.threshold_ma, 18.0);
  EXPECT_EQ(session->current.details.max_tolerated_ma, 55.0);
  EXPECT_EQ(session->current.details.notes, "first visit");
  EXPECT_EQ(session->current.recorded_by, "");
  // Migration 6 renamed the run states: 'completed' reads as done.
  auto run = SessionRepository(**db).GetRun(1);
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  EXPECT_EQ(run->state, RunState::kDone);
  EXPECT_TRUE(run->finished_at.has_value());
  auto user = UserRepository(**db).GetUser(user_id);
  ASSERT_TRUE(user.ok());
  EXPECT_EQ(user->name, "alice");
  auto audit = AuditLog(**db).List({});
  ASSERT_TRUE(audit.ok());
  ASSERT_EQ(audit->size(), 1u);
  EXPECT_EQ((*audit)[0].entry.request_summary, "{code: P07}");

  // The tables of migrations 2-4 exist and are empty on the upgraded file.
  auto count =
      (*db)->Read([](Connection& c) { return c.QueryText("SELECT count(*) FROM trials"); });
  ASSERT_TRUE(count.ok());
  EXPECT_EQ(*count, "0");
}

TEST_F(SqliteStorageTest, RefusesSchemaNewerThanSoftware) {
  ASSERT_TRUE(
      db_->Write([](Connection& c) { return c.ExecScript("PRAGMA user_version = 99"); }).ok());
  db_.reset();
  auto db = Database::Open(Options());
  ASSERT_FALSE(db.ok());
  EXPECT_EQ(db.status().code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_NE(db.status().message().find("99"), std::string::npos);
}

TEST(DatabaseOpen, RejectsBadOptions) {
  DatabaseOptions options;
  auto db = Database::Open(options);
  ASSERT_FALSE(db.ok());
  EXPECT_EQ(db.status().field(), "path");
  options.path = "/tmp/x.db";
  options.reader_count = 0;
  db = Database::Open(options);
  ASSERT_FALSE(db.ok());
  EXPECT_EQ(db.status().field(), "reader_count");
  options.reader_count = 1;
  options.target_schema_version = LatestSchemaVersion() + 1;
  db = Database::Open(options);
  ASSERT_FALSE(db.ok());
  EXPECT_EQ(db.status().field(), "target_schema_version");
}

TEST(DatabaseOpen, GarbageFileIsDataLoss) {
  const auto dir = testing::MakeTempDir("garbage");
  const std::string path = (dir / "garbage.db").string();
  {
    std::ofstream out(path, std::ios::binary);
    std::mt19937 rng(7);
    for (int i = 0; i < 8192; ++i) out.put(static_cast<char>(rng() & 0xff));
  }
  DatabaseOptions options;
  options.path = path;
  auto db = Database::Open(options);
  ASSERT_FALSE(db.ok());
  EXPECT_EQ(db.status().code(), api::ErrorCode::kDataLoss);
  EXPECT_NE(db.status().message().find("garbage.db"), std::string::npos);
  EXPECT_NE(db.status().message().find("corrupt"), std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST(DatabaseOpen, DamagedPageIsDataLoss) {
  const auto dir = testing::MakeTempDir("damaged");
  const std::string path = (dir / "damaged.db").string();
  DatabaseOptions options;
  options.path = path;
  {
    auto db = Database::Open(options);
    ASSERT_TRUE(db.ok());
    SubjectRepository subjects(**db);
    // One transaction: the nested Creates join it.
    auto filled = (*db)->Write([&](Connection&) -> api::Status {
      for (int i = 0; i < 400; ++i) {
        if (auto s = subjects.Create("S" + std::to_string(i), SubjectDetails{}); !s.ok()) {
          return s.status();
        }
      }
      return api::Status::Ok();
    });
    ASSERT_TRUE(filled.ok()) << filled.ToString();
  }  // closing the last connection checkpoints the WAL into the file
  ASSERT_FALSE(std::filesystem::exists(path + "-wal"));
  const auto size = std::filesystem::file_size(path);
  ASSERT_GT(size, 16u * 4096u);
  {
    // Overwrite the last quarter of the file (b-tree pages of the subject
    // tables and their indexes) with a fixed pattern.
    std::fstream file(path, std::ios::binary | std::ios::in | std::ios::out);
    file.seekp(static_cast<std::streamoff>(size - size / 4));
    for (std::uintmax_t i = 0; i < size / 4; ++i) file.put(static_cast<char>(0xA5));
  }
  auto db = Database::Open(options);
  ASSERT_FALSE(db.ok());
  EXPECT_EQ(db.status().code(), api::ErrorCode::kDataLoss);
  EXPECT_NE(db.status().message().find("restore it from a backup"), std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST_P(StorageTest, AppendOnlyTablesRefuseUpdateAndDelete) {
  auto subject = SubjectRepository(*db_).Create("A1", SubjectDetails{});
  ASSERT_TRUE(subject.ok());
  auto update = db_->Write([](Connection& c) -> api::Status {
    auto s = c.Prepare("UPDATE subjects SET code = 'B2'");
    if (!s.ok()) return s.status();
    return s->Run();
  });
  EXPECT_EQ(update.code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_NE(update.message().find("append-only"), std::string::npos);
  ASSERT_TRUE(AuditLog(*db_).Append({std::nullopt, "system", "start", "", "", "ok"}).ok());
  auto erase = db_->Write([](Connection& c) -> api::Status {
    auto s = c.Prepare("DELETE FROM audit_log");
    if (!s.ok()) return s.status();
    return s->Run();
  });
  EXPECT_EQ(erase.code(), api::ErrorCode::kFailedPrecondition);
  auto entries = AuditLog(*db_).List({});
  ASSERT_TRUE(entries.ok());
  EXPECT_EQ(entries->size(), 1u);
  auto still = SubjectRepository(*db_).Get(subject->id);
  ASSERT_TRUE(still.ok());
  EXPECT_EQ(still->code, "A1");
}

TEST_P(StorageTest, FailedTransactionRollsBackEveryRow) {
  SubjectRepository subjects(*db_);
  auto status = db_->Write([&](Connection&) -> api::Status {
    auto a = subjects.Create("R1", SubjectDetails{});  // joins this transaction
    if (!a.ok()) return a.status();
    auto b = subjects.Create("R1", SubjectDetails{});  // duplicate: fails
    return b.status();
  });
  EXPECT_EQ(status.code(), api::ErrorCode::kAlreadyExists);
  auto missing = subjects.GetByCode("R1");
  EXPECT_EQ(missing.status().code(), api::ErrorCode::kNotFound);
}

TEST_P(StorageTest, NestedReadsShareOneReaderConnection) {
  db_.reset();
  DatabaseOptions options = Options();
  options.reader_count = 1;  // a second reader would deadlock
  auto db = Database::Open(options);
  ASSERT_TRUE(db.ok());
  SubjectRepository subjects(**db);
  auto created = subjects.Create("N1", SubjectDetails{});
  ASSERT_TRUE(created.ok());
  auto code = (*db)->Read([&](Connection&) -> api::Result<std::string> {
    auto inner = subjects.Get(created->id);  // nested Read on this thread
    if (!inner.ok()) return inner.status();
    return inner->code;
  });
  ASSERT_TRUE(code.ok()) << code.status().ToString();
  EXPECT_EQ(*code, "N1");
}

TEST_F(SqliteStorageTest, BackupAndRestoreRoundTrip) {
  SubjectRepository subjects(*db_);
  for (int i = 0; i < 20; ++i) {
    ASSERT_TRUE(subjects.Create("B" + std::to_string(i), SubjectDetails{}).ok());
  }
  const std::string backup = (dir_ / "backup.db").string();
  ASSERT_TRUE(db_->Backup(backup).ok());
  ASSERT_TRUE(std::filesystem::exists(backup));
  // Writes after the backup are not in it.
  ASSERT_TRUE(subjects.Create("AFTER", SubjectDetails{}).ok());
  {
    DatabaseOptions options;
    options.path = backup;
    auto copy = Database::Open(options);
    ASSERT_TRUE(copy.ok()) << copy.status().ToString();
    auto list = SubjectRepository(**copy).List();
    ASSERT_TRUE(list.ok());
    EXPECT_EQ(list->size(), 20u);
  }
  ASSERT_TRUE(db_->RestoreFrom(backup).ok());
  auto list = subjects.List();
  ASSERT_TRUE(list.ok());
  EXPECT_EQ(list->size(), 20u);
  EXPECT_EQ(subjects.GetByCode("AFTER").status().code(), api::ErrorCode::kNotFound);
  EXPECT_TRUE(subjects.GetByCode("B19").ok());
  EXPECT_TRUE(db_->CheckIntegrity().ok());
  // The restored database accepts writes.
  EXPECT_TRUE(subjects.Create("AFTER", SubjectDetails{}).ok());
}

TEST_F(SqliteStorageTest, RestoreRefusesCorruptOrMissingBackup) {
  EXPECT_EQ(db_->RestoreFrom((dir_ / "none.db").string()).code(), api::ErrorCode::kNotFound);
  const std::string junk = (dir_ / "junk.db").string();
  {
    std::ofstream out(junk, std::ios::binary);
    for (int i = 0; i < 4096; ++i) out.put(static_cast<char>(i * 31));
  }
  EXPECT_EQ(db_->RestoreFrom(junk).code(), api::ErrorCode::kDataLoss);
  ASSERT_TRUE(SubjectRepository(*db_).Create("OK1", SubjectDetails{}).ok());
}

// Several reader threads and writer threads on one Database, plus a second
// Database on the same file (as another process would be): no caller ever
// sees an error, in particular not "database is locked".
TEST_P(StorageTest, ConcurrentReadersAndWritersNeverSeeLocked) {
  SubjectRepository subjects(*db_);
  auto seed_subject = subjects.Create("C0", SubjectDetails{});
  ASSERT_TRUE(seed_subject.ok());
  DatabaseOptions second_options = Options();
  second_options.busy_timeout = std::chrono::milliseconds(5);  // force retries
  second_options.bench_id = "bench-b";  // another server (PostgreSQL refuses two on one bench)
  second_options.lock_file = false;     // SQLite refuses a second on one file: as if it were not
  auto second = Database::Open(second_options);
  ASSERT_TRUE(second.ok());

  constexpr int kWriters = 2;
  constexpr int kWritesPerWriter = 60;
  constexpr int kReaders = 4;
  constexpr int kReadsPerReader = 150;
  std::atomic<int> errors{0};
  std::vector<std::string> first_errors(kWriters + kReaders + 1);
  std::vector<std::thread> threads;
  for (int w = 0; w < kWriters; ++w) {
    threads.emplace_back([&, w] {
      SubjectRepository repo(*db_);
      for (int i = 0; i < kWritesPerWriter; ++i) {
        auto r = repo.Create("W" + std::to_string(w) + "_" + std::to_string(i), SubjectDetails{});
        if (!r.ok() && errors.fetch_add(1) == 0) first_errors[w] = r.status().ToString();
      }
    });
  }
  threads.emplace_back([&] {
    SubjectRepository repo(**second);
    for (int i = 0; i < kWritesPerWriter; ++i) {
      auto r = repo.Create("X_" + std::to_string(i), SubjectDetails{});
      if (!r.ok() && errors.fetch_add(1) == 0) first_errors[kWriters] = r.status().ToString();
    }
  });
  for (int rd = 0; rd < kReaders; ++rd) {
    threads.emplace_back([&, rd] {
      SubjectRepository repo(*db_);
      std::size_t last = 0;
      for (int i = 0; i < kReadsPerReader; ++i) {
        auto list = repo.List();
        if (!list.ok()) {
          if (errors.fetch_add(1) == 0) first_errors[kWriters + 1 + rd] = list.status().ToString();
          continue;
        }
        // Snapshots only grow.
        if (list->size() < last) errors.fetch_add(1);
        last = list->size();
        if (!repo.Get(seed_subject->id).ok()) errors.fetch_add(1);
      }
    });
  }
  for (auto& t : threads) t.join();
  std::string first;
  for (const auto& e : first_errors)
    if (!e.empty()) first = e;
  EXPECT_EQ(errors.load(), 0) << first;
  auto list = subjects.List();
  ASSERT_TRUE(list.ok());
  EXPECT_EQ(list->size(), 1u + kWriters * kWritesPerWriter + kWritesPerWriter);
}

// Two servers on one database: each sees only its own bench's
// unfinished runs and e-stop latch, moves only its own runs, and reads the
// other's like any analyst.
TEST_P(StorageTest, RunsAndLatchesBelongToTheirBench) {
  const Session session = MakeSession("K1");
  DatabaseOptions other = Options();
  other.bench_id = "bench-b";
  other.lock_file = false;  // SQLite: a file has one server; here, as if it had two
  auto b = Database::Open(other);
  ASSERT_TRUE(b.ok()) << b.status().ToString();
  SessionRepository on_a(*db_);
  SessionRepository on_b(**b);
  auto run_a = on_a.CreateRun(session.id, {"irc_ramp", "1", "{}"});
  auto run_b = on_b.CreateRun(session.id, {"free_swing", "1", "{}"});
  ASSERT_TRUE(run_a.ok() && run_b.ok());
  EXPECT_EQ(run_a->bench_id, "bench-a");
  EXPECT_EQ(run_b->bench_id, "bench-b");

  auto open_a = on_a.ListUnfinishedRuns();
  ASSERT_TRUE(open_a.ok());
  ASSERT_EQ(open_a->size(), 1u);
  EXPECT_EQ(open_a->front().id, run_a->id);
  auto seen_by_b = on_b.GetRun(run_a->id);
  ASSERT_TRUE(seen_by_b.ok());
  EXPECT_EQ(seen_by_b->bench_id, "bench-a");
  auto moved = on_b.RecordRunState(run_a->id, RunState::kAborted, "not mine");
  EXPECT_EQ(moved.status().code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_NE(moved.status().message().find("bench-a"), std::string::npos);
  EXPECT_TRUE(on_b.RecordRunState(run_b->id, RunState::kRunning).ok());
  auto listed = on_a.ListRuns(session.id);
  ASSERT_TRUE(listed.ok());
  EXPECT_EQ(listed->size(), 2u);

  ASSERT_TRUE(EStopLatchRepository(*db_).RecordLatched("http (cora)", "cora").ok());
  auto latched_a = EStopLatchRepository(*db_).Current();
  auto latched_b = EStopLatchRepository(**b).Current();
  ASSERT_TRUE(latched_a.ok() && latched_b.ok());
  EXPECT_TRUE(latched_a->has_value());
  EXPECT_FALSE(latched_b->has_value());
}

TEST_F(PostgresStorageTest, RecordsItsMigrationsAndRefusesANewerSchema) {
  auto recorded = db_->Read([](Connection& c) {
    return c.QueryText("SELECT string_agg(version::text, ',' ORDER BY version) FROM schema_migrations");
  });
  ASSERT_TRUE(recorded.ok()) << recorded.status().ToString();
  EXPECT_EQ(*recorded, "11,12,13,14,15,16,17,18,19");
  ASSERT_TRUE(db_->Write([](Connection& c) {
                   return c.ExecScript(
                       "INSERT INTO schema_migrations VALUES (99, 'from the future', 'x')");
                 }).ok());
  db_.reset();
  auto db = Database::Open(Options());
  ASSERT_FALSE(db.ok());
  EXPECT_EQ(db.status().code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_NE(db.status().message().find("99"), std::string::npos);
}

TEST_F(PostgresStorageTest, FileBackupsAreRefusedNamingPgDump) {
  const api::Status backup = db_->Backup((dir_ / "x.db").string());
  EXPECT_EQ(backup.code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_NE(backup.message().find("pg_dump"), std::string::npos);
  EXPECT_EQ(db_->RestoreFrom((dir_ / "x.db").string()).code(),
            api::ErrorCode::kFailedPrecondition);
  EXPECT_TRUE(db_->CheckIntegrity().ok());
}

TEST_F(PostgresStorageTest, ASecondServerForTheSameBenchIsRefused) {
  auto same = Database::Open(Options());
  ASSERT_FALSE(same.ok());
  EXPECT_EQ(same.status().code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_NE(same.status().message().find("bench-a"), std::string::npos);
  DatabaseOptions other = Options();
  other.bench_id = "bench-b";
  EXPECT_TRUE(Database::Open(other).ok());
  db_.reset();  // the bench is free again once its server has gone
  EXPECT_TRUE(Database::Open(Options()).ok());
}

TEST_F(PostgresStorageTest, UnreachableServerIsUnavailableWithoutThePassword) {
  DatabaseOptions options;
  options.path = "postgresql://fesbench:s3cret@127.0.0.1:1/none?connect_timeout=2";
  auto db = Database::Open(options);
  ASSERT_FALSE(db.ok());
  EXPECT_EQ(db.status().code(), api::ErrorCode::kUnavailable);
  EXPECT_EQ(db.status().message().find("s3cret"), std::string::npos) << db.status().message();
  EXPECT_NE(db.status().message().find("127.0.0.1"), std::string::npos);
}

// Two servers writing at once: both append versions of the same
// leg's parameter set and audit rows from two threads each. Serializable
// transactions refuse the loser of each race, which is retried: no version
// is lost or given twice, every id is unique, and each server reads all.
TEST_F(PostgresStorageTest, TwoServersWritingAtOnceLoseAndRepeatNothing) {
  const Session session = MakeSession("M1");
  DatabaseOptions other = Options();
  other.bench_id = "bench-b";
  auto b = Database::Open(other);
  ASSERT_TRUE(b.ok()) << b.status().ToString();
  constexpr int kThreadsPerServer = 2;
  constexpr int kSetsPerThread = 15;
  std::atomic<int> errors{0};
  std::string first_error;
  std::mutex first_error_mutex;
  std::vector<std::thread> threads;
  for (Database* server : {db_.get(), b->get()}) {
    for (int t = 0; t < kThreadsPerServer; ++t) {
      threads.emplace_back([&, server, t] {
        ParameterSetRepository sets(*server);
        AuditLog log(*server);
        for (int i = 0; i < kSetsPerThread; ++i) {
          auto stored = sets.Insert({session.subject_id, session.leg_id,
                                     model::ExampleParameterSet(), std::nullopt, std::nullopt});
          auto audited = log.Append({std::nullopt, "t" + std::to_string(t), "store", "", "", "ok"});
          if ((!stored.ok() || !audited.ok()) && errors.fetch_add(1) == 0) {
            std::lock_guard lock(first_error_mutex);
            first_error = !stored.ok() ? stored.status().ToString() : audited.status().ToString();
          }
        }
      });
    }
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(errors.load(), 0) << first_error;

  constexpr int kTotal = 2 * kThreadsPerServer * kSetsPerThread;
  for (Database* server : {db_.get(), b->get()}) {
    auto versions = server->Read([&](Connection& c) -> api::Result<std::string> {
      return c.QueryText(
          "SELECT count(*) || ',' || count(DISTINCT id) || ',' || count(DISTINCT version) || ','"
          " || min(version) || ',' || max(version) FROM parameter_sets");
    });
    ASSERT_TRUE(versions.ok()) << versions.status().ToString();
    EXPECT_EQ(*versions, std::to_string(kTotal) + "," + std::to_string(kTotal) + "," +
                             std::to_string(kTotal) + ",1," + std::to_string(kTotal));
    auto audit = AuditLog(*server).List({});
    ASSERT_TRUE(audit.ok());
    EXPECT_EQ(audit->size(), static_cast<std::size_t>(kTotal));
  }
}

// New sets as events across servers: a set stored through one
// Database reaches the other's listener once it commits (NOTIFY), and a
// server's own sets reach its listener once, from its own commit.
TEST_F(PostgresStorageTest, SetsStoredByAnotherServerArriveAsEvents) {
  const Session session = MakeSession("E1");
  DatabaseOptions other = Options();
  other.bench_id = "bench-b";
  auto b = Database::Open(other);
  ASSERT_TRUE(b.ok()) << b.status().ToString();
  std::mutex mutex;
  std::condition_variable arrived;
  std::vector<std::int64_t> seen_by_a, seen_by_b;
  db_->SetParameterSetListener([&](const Database::ParameterSetStored& e) {
    std::lock_guard lock(mutex);
    seen_by_a.push_back(e.id);
    arrived.notify_all();
  });
  (*b)->SetParameterSetListener([&](const Database::ParameterSetStored& e) {
    std::lock_guard lock(mutex);
    EXPECT_EQ(e.subject_id, session.subject_id);
    EXPECT_EQ(e.leg_id, session.leg_id);
    seen_by_b.push_back(e.id);
    arrived.notify_all();
  });
  auto stored = ParameterSetRepository(*db_).Insert(
      {session.subject_id, session.leg_id, model::ExampleParameterSet(), std::nullopt,
       std::nullopt});
  ASSERT_TRUE(stored.ok()) << stored.status().ToString();
  // A transaction that rolls back notifies nobody.
  const api::Status rolled_back = db_->Write([&](Connection&) -> api::Status {
    auto set = ParameterSetRepository(*db_).Insert(
        {session.subject_id, session.leg_id, model::ExampleParameterSet(), std::nullopt,
         std::nullopt});
    if (!set.ok()) return set.status();
    return api::Status::Internal("changed my mind");
  });
  ASSERT_FALSE(rolled_back.ok());
  {
    std::unique_lock lock(mutex);
    EXPECT_TRUE(arrived.wait_for(lock, std::chrono::seconds(10), [&] { return !seen_by_b.empty(); }));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // anything more would be wrong
  std::lock_guard lock(mutex);
  EXPECT_EQ(seen_by_a, std::vector<std::int64_t>{stored->id});
  EXPECT_EQ(seen_by_b, std::vector<std::int64_t>{stored->id});
  db_->SetParameterSetListener({});
  (*b)->SetParameterSetListener({});
}

INSTANTIATE_TEST_SUITE_P(Engines, StorageTest,
                         ::testing::Values(Engine::kSqlite, Engine::kPostgres),
                         [](const ::testing::TestParamInfo<Engine>& info) {
                           return info.param == Engine::kSqlite ? "sqlite" : "postgres";
                         });

}  // namespace
}  // namespace fesbench::storage
