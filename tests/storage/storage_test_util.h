#pragma once

// Shared fixture for the storage tests: a fresh database in a temporary
// directory, a deterministic clock (1 s per call from 2026-01-01T00:00:00Z),
// and helpers that create the rows most tests need.

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

inline UtcTime Epoch2026() {
  return std::chrono::sys_days{std::chrono::year{2026} / 1 / 1} + std::chrono::microseconds(0);
}

/// A clock that advances one second per call; `ticks` counts the calls.
inline std::function<UtcTime()> SteppingClock(std::shared_ptr<std::atomic<long long>> ticks) {
  return [ticks] { return Epoch2026() + std::chrono::seconds(ticks->fetch_add(1)); };
}

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

class StorageTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = MakeTempDir("t");
    path_ = (dir_ / "fesbench.db").string();
    auto db = Database::Open(Options());
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    db_ = std::move(*db);
    ticks_->store(0);  // the first row a test writes is stamped 2026-01-01T00:00:00Z
  }
  void TearDown() override {
    db_.reset();
    std::filesystem::remove_all(dir_);
  }

  DatabaseOptions Options() const {
    DatabaseOptions options;
    options.path = path_;
    options.clock = clock_;
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

  std::filesystem::path dir_;
  std::string path_;
  std::shared_ptr<std::atomic<long long>> ticks_ = std::make_shared<std::atomic<long long>>(0);
  std::function<UtcTime()> clock_ = SteppingClock(ticks_);
  std::unique_ptr<Database> db_;
};

}  // namespace fesbench::storage::testing
