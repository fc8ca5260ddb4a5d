#pragma once

// Shared fixtures for the storage tests: a fresh database (an SQLite file in
// a temporary directory, or a scratch PostgreSQL database), a deterministic
// clock (1 s per call from 2026-01-01T00:00:00Z), and helpers that create
// the rows most tests need.

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <numbers>
#include <string>

#include "api/trial.h"
#include "storage/database.h"
#include "storage/sessions.h"
#include "storage/subjects.h"
#include "tests/support/postgres_server.h"

namespace fesbench::storage::testing {

inline std::filesystem::path MakeTempDir(const std::string& tag) {
  static std::atomic<int> counter{0};
  const auto dir = std::filesystem::temp_directory_path() /
                   ("fesbench_storage_" + tag + "_" + std::to_string(::getpid()) + "_" +
                    std::to_string(counter++));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

inline api::UtcTime Epoch2026() {
  return std::chrono::sys_days{std::chrono::year{2026} / 1 / 1} + std::chrono::microseconds(0);
}

/// A clock whose UTC advances one second per reading, from
/// 2026-01-01T00:00:00Z; `ticks` counts the readings.
class SteppingClock : public api::Clock {
 public:
  explicit SteppingClock(std::shared_ptr<std::atomic<long long>> ticks)
      : ticks_(std::move(ticks)) {}
  double MonotonicSeconds() override { return static_cast<double>(ticks_->load()); }
  api::UtcTime UtcNow() override { return Epoch2026() + std::chrono::seconds(ticks_->fetch_add(1)); }
  void SleepFor(double) override {}

 private:
  std::shared_ptr<std::atomic<long long>> ticks_;
};

/// A 200 Hz trial with t_s, angle_deg, torque_nm, stim_ma (closed-form values).
inline api::Trial MakeTrial(std::size_t samples, double phase = 0.0) {
  api::Trial trial;
  trial.name = "free_swing";
  trial.start_time_unix_ms = 1767225600000;
  trial.sample_rate_hz = 200.0;
  std::vector<double> t(samples), angle(samples), torque(samples), stim(samples);
  for (std::size_t i = 0; i < samples; ++i) {
    t[i] = static_cast<double>(i) / 200.0;
    angle[i] = 60.0 + 30.0 * std::sin(2.0 * std::numbers::pi * t[i] + phase);
    torque[i] = 5.0 * std::cos(2.0 * std::numbers::pi * t[i] + phase);
    stim[i] = static_cast<double>(i % 7);
  }
  trial.SetChannel("t_s", t);
  trial.SetChannel("angle_deg", angle);
  trial.SetChannel("torque_nm", torque);
  trial.SetChannel("stim_ma", stim);
  return trial;
}

// A fresh database on one engine: a file in a temporary directory, or a
// scratch database on the tests' PostgreSQL server (tests/support).
class StorageFixture {
 protected:
  // Opens the database; false (with `skip_`) when PostgreSQL is not
  // installed here. Any other failure to get a database fails the test.
  bool OpenFresh(Engine engine) {
    engine_ = engine;
    dir_ = MakeTempDir("t");
    if (engine == Engine::kPostgres) {
      scratch_ = std::make_unique<::fesbench::testing::ScratchDatabase>();
      if (!scratch_->ok()) {
        skip_ = scratch_->skip_reason();
        if (scratch_->skippable()) return false;
        ADD_FAILURE() << skip_;
        return true;
      }
      path_ = scratch_->url();
    } else {
      path_ = (dir_ / "fesbench.db").string();
    }
    auto db = Database::Open(Options());
    EXPECT_TRUE(db.ok()) << db.status().ToString();
    if (!db.ok()) return true;
    db_ = std::move(*db);
    ticks_->store(0);  // the first row a test writes is stamped 2026-01-01T00:00:00Z
    return true;
  }
  void Close() {
    db_.reset();
    scratch_.reset();
    std::filesystem::remove_all(dir_);
  }

  DatabaseOptions Options() const {
    DatabaseOptions options;
    options.path = path_;
    options.clock = clock_.get();
    options.bench_id = "bench-a";
    return options;
  }

  // A subject "S<n>" with a right leg and one session; returns the session.
  Session MakeSession(const std::string& code) {
    SubjectRepository subjects(*db_);
    auto subject = subjects.Create(code, SubjectDetails{});
    EXPECT_TRUE(subject.ok()) << subject.status().ToString();
    auto leg = subjects.AddLeg(subject->id, Side::kRight);
    EXPECT_TRUE(leg.ok()) << leg.status().ToString();
    SessionDetails details;
    details.date = "2026-01-02";
    details.accelerometer_placement = "shank";
    auto session = SessionRepository(*db_).Create(subject->id, leg->id, details);
    EXPECT_TRUE(session.ok()) << session.status().ToString();
    return *session;
  }

  // The query plan of `sql` (its ?N bound to '1'): SQLite's EXPLAIN QUERY
  // PLAN details, or PostgreSQL's EXPLAIN with sequential scans disabled
  // (tables this small would be scanned; the question is whether an index
  // serves the query, in order, with no sort).
  api::Result<std::string> PlanOf(const std::string& sql) {
    return db_->Read([&](Connection& c) -> api::Result<std::string> {
      const bool postgres = c.engine() == Engine::kPostgres;
      std::string text = sql;
      if (postgres) {
        if (auto s = c.ExecScript("SET LOCAL enable_seqscan = off"); !s.ok()) return s;
        for (int n = 9; n >= 1; --n) {
          const std::string key = "?" + std::to_string(n);
          for (auto at = text.find(key); at != std::string::npos; at = text.find(key)) {
            text.replace(at, key.size(), "'1'");
          }
        }
      }
      auto s = c.Prepare((postgres ? "EXPLAIN " : "EXPLAIN QUERY PLAN ") + text);
      if (!s.ok()) return s.status();
      if (!postgres) {
        for (int n = 1; n <= 9 && sql.find("?" + std::to_string(n)) != std::string::npos; ++n) {
          s->Bind(n, std::int64_t{1});
        }
      }
      std::string all_rows;
      while (true) {
        auto row = s->Step();
        if (!row.ok()) return row.status();
        if (!*row) break;
        all_rows += s->Text(postgres ? 0 : 3) + "\n";
      }
      return all_rows;
    });
  }
  // The plan reads `index` as a range, with no sort: SQLite "SEARCH … INDEX
  // <index>" (or "INTEGER PRIMARY KEY" for the rowid) without a temporary
  // B-tree; PostgreSQL an index scan on <index> (<table>_pkey for the id)
  // without a Sort node.
  void ExpectIndexRange(const std::string& sql, const std::string& index,
                        const std::string& primary_key_of = "") {
    auto plan = PlanOf(sql);
    ASSERT_TRUE(plan.ok()) << plan.status().ToString();
    if (engine_ == Engine::kPostgres) {
      const std::string name = primary_key_of.empty() ? index : primary_key_of + "_pkey";
      EXPECT_NE(plan->find("Index"), std::string::npos) << sql << "\n" << *plan;
      EXPECT_NE(plan->find(name), std::string::npos) << sql << "\n" << *plan;
      EXPECT_EQ(plan->find("Sort"), std::string::npos) << "a sort: " << sql << "\n" << *plan;
    } else {
      EXPECT_NE(plan->find("SEARCH"), std::string::npos) << sql << "\n" << *plan;
      EXPECT_NE(plan->find(primary_key_of.empty() ? index : "INTEGER PRIMARY KEY"),
                std::string::npos)
          << sql << "\n"
          << *plan;
      EXPECT_EQ(plan->find("TEMP B-TREE"), std::string::npos) << "a sort: " << sql << "\n" << *plan;
    }
  }

  Engine engine_ = Engine::kSqlite;
  std::filesystem::path dir_;
  std::string path_;
  std::unique_ptr<::fesbench::testing::ScratchDatabase> scratch_;
  std::string skip_;
  std::shared_ptr<std::atomic<long long>> ticks_ = std::make_shared<std::atomic<long long>>(0);
  std::unique_ptr<SteppingClock> clock_ = std::make_unique<SteppingClock>(ticks_);
  std::unique_ptr<Database> db_;
};

// A test that runs on both engines (instantiated once, in database_test.cc,
// as sqlite/… and postgres/…; skipped with the reason where the PostgreSQL
// server binaries are missing).
class StorageTest : public ::testing::TestWithParam<Engine>, protected StorageFixture {
 protected:
  void SetUp() override {
    if (!OpenFresh(GetParam())) GTEST_SKIP() << skip_;
    ASSERT_NE(db_, nullptr);
  }
  void TearDown() override { Close(); }
};

// A test of what only the SQLite engine has (pragmas, file backups, upgrades
// from before PostgreSQL support).
class SqliteStorageTest : public ::testing::Test, protected StorageFixture {
 protected:
  void SetUp() override {
    OpenFresh(Engine::kSqlite);
    ASSERT_NE(db_, nullptr);
  }
  void TearDown() override { Close(); }
};

// A test of what only the PostgreSQL engine has.
class PostgresStorageTest : public ::testing::Test, protected StorageFixture {
 protected:
  void SetUp() override {
    if (!OpenFresh(Engine::kPostgres)) GTEST_SKIP() << skip_;
    ASSERT_NE(db_, nullptr);
  }
  void TearDown() override { Close(); }
};

}  // namespace fesbench::storage::testing
