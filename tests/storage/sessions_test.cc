#include "storage/sessions.h"

#include <gtest/gtest.h>

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
