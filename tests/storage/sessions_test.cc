#include "storage/sessions.h"

#include <gtest/gtest.h>

#include "model/parameter_set.h"
#include "storage/parameter_sets.h"
#include "storage_test_util.h"

namespace fesbench::storage {
namespace {

using testing::StorageTest;

TEST_P(StorageTest, SessionCreateCorrectAndList) {
  SubjectRepository subjects(*db_);
  auto subject = subjects.Create("S1", SubjectDetails{});
  ASSERT_TRUE(subject.ok());
  auto leg = subjects.AddLeg(subject->id, Side::kLeft);
  ASSERT_TRUE(leg.ok());
  SessionRepository sessions(*db_);
  SessionDetails details{"2026-03-04", "shank, 15 cm below the knee", 21.0, 60.0, "calm"};
  auto session = sessions.Create(subject->id, leg->id, details);
  ASSERT_TRUE(session.ok()) << session.status().ToString();
  EXPECT_EQ(session->current.details, details);
  EXPECT_EQ(session->leg_id, leg->id);

  SessionDetails fixed = details;
  fixed.max_tolerated_ma = 58.0;
  auto corrected = sessions.Correct(session->id, fixed, "typo in max tolerated");
  ASSERT_TRUE(corrected.ok());
  EXPECT_EQ(corrected->current.revision, 2);
  EXPECT_EQ(corrected->current.corrects_id, session->current.id);
  EXPECT_EQ(corrected->current.details.max_tolerated_ma, 58.0);
  auto revisions = sessions.Revisions(session->id);
  ASSERT_TRUE(revisions.ok());
  ASSERT_EQ(revisions->size(), 2u);
  EXPECT_EQ((*revisions)[0].details.max_tolerated_ma, 60.0);

  auto list = sessions.ListForSubject(subject->id);
  ASSERT_TRUE(list.ok());
  ASSERT_EQ(list->size(), 1u);
  EXPECT_EQ(list->front().current.details.max_tolerated_ma, 58.0);
}

TEST_P(StorageTest, SessionBadInputNamesTheProblem) {
  SubjectRepository subjects(*db_);
  auto a = subjects.Create("A", SubjectDetails{});
  auto b = subjects.Create("B", SubjectDetails{});
  ASSERT_TRUE(a.ok() && b.ok());
  auto leg_b = subjects.AddLeg(b->id, Side::kRight);
  ASSERT_TRUE(leg_b.ok());
  SessionRepository sessions(*db_);
  SessionDetails ok{"2026-03-04", "shank", std::nullopt, std::nullopt, ""};
  auto wrong_leg = sessions.Create(a->id, leg_b->id, ok);
  EXPECT_EQ(wrong_leg.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(wrong_leg.status().field(), "leg_id");
  EXPECT_EQ(sessions.Create(77, leg_b->id, ok).status().message(), "subject 77 not found");
  EXPECT_EQ(sessions.Create(b->id, 78, ok).status().message(), "leg 78 not found");
  SessionDetails bad = ok;
  bad.date = "2026-13-01";
  EXPECT_EQ(sessions.Create(b->id, leg_b->id, bad).status().field(), "date");
  bad = ok;
  bad.threshold_ma = 30;
  bad.max_tolerated_ma = 20;
  EXPECT_EQ(sessions.Create(b->id, leg_b->id, bad).status().field(), "max_tolerated_ma");
  bad = ok;
  bad.threshold_ma = 120;
  EXPECT_EQ(sessions.Create(b->id, leg_b->id, bad).status().field(), "threshold_ma");
  EXPECT_EQ(sessions.Get(5).status().code(), api::ErrorCode::kNotFound);
}

TEST_P(StorageTest, RunStateIsTheLastEvent) {
  const Session session = MakeSession("R1");
  SessionRepository sessions(*db_);
  auto run = sessions.CreateRun(session.id, {"irc_ramp", "1.0", R"({"ramp_ma_per_s": 2})"});
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  EXPECT_EQ(run->state, RunState::kQueued);
  EXPECT_FALSE(run->started_at.has_value());
  auto running = sessions.RecordRunState(run->id, RunState::kRunning);
  ASSERT_TRUE(running.ok()) << running.status().ToString();
  ASSERT_TRUE(running->started_at.has_value());
  auto done = sessions.RecordRunState(run->id, RunState::kDone, "3 trials");
  ASSERT_TRUE(done.ok());
  EXPECT_EQ(done->state, RunState::kDone);
  EXPECT_EQ(done->message, "3 trials");
  ASSERT_TRUE(done->finished_at.has_value());
  EXPECT_EQ(*done->finished_at - *done->started_at, std::chrono::seconds(1));
  auto again = sessions.RecordRunState(run->id, RunState::kRunning);
  EXPECT_EQ(again.status().code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_EQ(again.status().message(), "run 1 cannot go from done to running");
  auto list = sessions.ListRuns(session.id);
  ASSERT_TRUE(list.ok());
  ASSERT_EQ(list->size(), 1u);
  EXPECT_EQ(list->front().parameters_json, R"({"ramp_ma_per_s": 2})");

  EXPECT_EQ(sessions.CreateRun(session.id, {"x", "1", "{not json"}).status().field(),
            "parameters_json");
  EXPECT_EQ(sessions.CreateRun(session.id, {"", "1", "{}"}).status().field(), "protocol_name");
  EXPECT_EQ(sessions.CreateRun(999, {"x", "1", "{}"}).status().code(), api::ErrorCode::kNotFound);
  EXPECT_EQ(sessions.GetRun(999).status().code(), api::ErrorCode::kNotFound);
  EXPECT_EQ(sessions.RecordRunState(999, RunState::kRunning).status().code(),
            api::ErrorCode::kNotFound);
}

}  // namespace
}  // namespace fesbench::storage

namespace fesbench::storage {
namespace {

// Migration 19 (docs/ARCHITECTURE.md, "Runs"): runs that ended before runs
// stored their outcome get the one the software of schema 18 showed — the
// tolerance test's session revision (found once by its reason), the set a
// run stored, the reason of a run that failed or aborted — and read back
// as before.
class RunOutcomeMigrationTest : public ::testing::TestWithParam<Engine>,
                                protected testing::StorageFixture {
 protected:
  void SetUp() override {
    if (!OpenFresh(GetParam())) GTEST_SKIP() << skip_;
    ASSERT_NE(db_, nullptr);
    // A fresh database at schema 18.
    db_.reset();
    if (GetParam() == Engine::kPostgres) {
      scratch_ = std::make_unique<::fesbench::testing::ScratchDatabase>();
      ASSERT_TRUE(scratch_->ok()) << scratch_->skip_reason();
      path_ = scratch_->url();
    } else {
      std::filesystem::remove(path_);
    }
    DatabaseOptions v18 = Options();
    v18.target_schema_version = 18;
    auto db = Database::Open(v18);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    db_ = std::move(*db);
  }
  void TearDown() override { Close(); }

  // A run as schema 18 stored it (today's repositories read schema 19): its
  // row, running, then `state` unless it is still running; ids from 1.
  std::int64_t Ended(const Session& session, const char* protocol, RunState state,
                     const std::string& message = {}) {
    const std::int64_t id = ++runs_;
    std::string sql =
        "INSERT INTO runs (id, session_id, protocol_name, protocol_version, parameters_json,"
        " created_at_utc, bench_id) VALUES (" + std::to_string(id) + ", " +
        std::to_string(session.id) + ", '" + protocol +
        "', '1', '{}', '2026-01-01T00:00:00.000000Z', 'bench-a');"
        "INSERT INTO run_events (run_id, state, message, at_utc) VALUES (" + std::to_string(id) +
        ", 'running', '', '2026-01-01T00:00:01.000000Z');";
    if (state != RunState::kRunning) {
      sql += "INSERT INTO run_events (run_id, state, message, at_utc) VALUES (" +
             std::to_string(id) + ", '" + std::string(api::RunStateName(state)) + "', '" + message +
             "', '2026-01-01T00:00:02.000000Z');";
    }
    EXPECT_TRUE(db_->Write([&](Connection& c) { return c.ExecScript(sql); }).ok());
    return id;
  }
  std::int64_t runs_ = 0;
};

TEST_P(RunOutcomeMigrationTest, RunsThatEndedBeforeReadBackAsBefore) {
  const Session session = MakeSession("M19");
  SessionRepository sessions(*db_);
  // A tolerance test that stored its limits as revision 2 of the session.
  const std::int64_t tolerance = Ended(session, "tolerance_test", RunState::kDone);
  SessionDetails measured = session.current.details;
  measured.threshold_ma = 12.345678901234567;
  measured.max_tolerated_ma = 31.5;
  ASSERT_TRUE(sessions
                  .Correct(session.id, measured,
                           "tolerance_test run " + std::to_string(tolerance), "cora")
                  .ok());
  // A rapid run whose set names it (schema 13).
  const std::int64_t rapid = Ended(session, "rapid_parameterisation", RunState::kDone);
  NewParameterSet set{session.subject_id, session.leg_id, model::ExampleParameterSet(),
                      std::nullopt, std::nullopt, rapid};
  auto stored_set = ParameterSetRepository(*db_).Insert(set);
  ASSERT_TRUE(stored_set.ok()) << stored_set.status().ToString();
  const std::int64_t aborted = Ended(session, "isometric_ramp_irc", RunState::kAborted, "cancelled by cora");
  const std::int64_t plain = Ended(session, "isometric_ramp_irc", RunState::kDone);
  const std::int64_t running = Ended(session, "isometric_step_irc", RunState::kRunning);
  db_.reset();

  auto migrated = Database::Open(Options());
  ASSERT_TRUE(migrated.ok()) << migrated.status().ToString();
  db_ = std::move(*migrated);
  SessionRepository after(*db_);
  const auto view_of = [&](std::int64_t id) {
    auto read = after.GetRun(id);
    EXPECT_TRUE(read.ok()) << read.status().ToString();
    return read.ok() ? api::RunViewToJson(RunViewOf(*read)) : nlohmann::json();
  };
  const nlohmann::json t = view_of(tolerance);
  EXPECT_EQ(t.at("result"), nlohmann::json({{"threshold_ma", 12.345678901234567},
                                            {"max_tolerated_ma", 31.5},
                                            {"session_revision", 2}}));
  EXPECT_EQ(t.at("outcome").at("session_revision"), 2);
  EXPECT_FALSE(t.contains("tolerance"));  // what the detector measured was never stored
  EXPECT_EQ(t.at("values"), nlohmann::json::object());
  const nlohmann::json r = view_of(rapid);
  EXPECT_EQ(r.at("parameter_set_id"), stored_set->id);
  EXPECT_EQ(r.at("result"), nlohmann::json({{"parameter_set_id", stored_set->id}}));
  const nlohmann::json a = view_of(aborted);
  EXPECT_EQ(a.at("state"), "aborted");
  EXPECT_EQ(a.at("reason"), "cancelled by cora");
  EXPECT_EQ(a.at("outcome").at("reason"), "cancelled by cora");
  EXPECT_TRUE(a.at("result").is_null());
  const nlohmann::json p = view_of(plain);
  EXPECT_TRUE(p.at("result").is_null());
  EXPECT_EQ(p.at("outcome").at("state"), "done");
  // A run still going has no outcome until it ends.
  EXPECT_TRUE(view_of(running).at("outcome").is_null());
}

INSTANTIATE_TEST_SUITE_P(Engines, RunOutcomeMigrationTest,
                         ::testing::Values(Engine::kSqlite, Engine::kPostgres),
                         [](const ::testing::TestParamInfo<Engine>& info) {
                           return info.param == Engine::kSqlite ? "sqlite" : "postgres";
                         });

}  // namespace
}  // namespace fesbench::storage
