// The stored e-stop latch (docs/SAFETY.md) and the runs a stopped process left
// unfinished: rows only ever appended; the latch is the last row; it
// survives closing and reopening the database.
#include "storage/estop_latch.h"

#include "storage/connection.h"
#include "storage_test_util.h"

namespace fesbench::storage::testing {
namespace {

TEST_P(StorageTest, TheEStopLatchIsTheLastRowAndSurvivesReopening) {
  EStopLatchRepository latch(*db_);
  auto none = latch.Current();
  ASSERT_TRUE(none.ok()) << none.status().ToString();
  EXPECT_FALSE(none->has_value()) << "never pressed: not latched";

  ASSERT_TRUE(latch.RecordLatched("http (cora)", "cora").ok());
  ASSERT_TRUE(latch.RecordLatched("dds (ana)", "ana").ok());
  auto latched = latch.Current();
  ASSERT_TRUE(latched.ok());
  ASSERT_TRUE(latched->has_value());
  EXPECT_EQ((*latched)->source, "dds (ana)");
  EXPECT_EQ((*latched)->recorded_by, "ana");
  EXPECT_EQ(api::FormatUtc((*latched)->at), "2026-01-01T00:00:01.000000Z");

  db_.reset();  // a restart
  auto reopened = Database::Open(Options());
  ASSERT_TRUE(reopened.ok());
  db_ = std::move(*reopened);
  EStopLatchRepository after(*db_);
  ASSERT_TRUE(after.Current()->has_value());
  ASSERT_TRUE(after.RecordCleared("cora").ok());
  EXPECT_FALSE(after.Current()->has_value());

  // Append-only: history is never rewritten.
  auto rewrite = db_->Write([](Connection& c) { return c.ExecScript("DELETE FROM estop_events"); });
  EXPECT_FALSE(rewrite.ok());
  auto update =
      db_->Write([](Connection& c) { return c.ExecScript("UPDATE estop_events SET latched = 0"); });
  EXPECT_FALSE(update.ok());
}

TEST_P(StorageTest, UnfinishedRunsAreThoseLastQueuedOrRunning) {
  const Session session = MakeSession("U1");
  SessionRepository sessions(*db_);
  auto queued = sessions.CreateRun(session.id, {"a", "1", "{}"});
  auto running = sessions.CreateRun(session.id, {"b", "1", "{}"});
  auto failed = sessions.CreateRun(session.id, {"c", "1", "{}"});
  ASSERT_TRUE(queued.ok() && running.ok() && failed.ok());
  ASSERT_TRUE(sessions.RecordRunState(running->id, RunState::kRunning).ok());
  ASSERT_TRUE(sessions.RecordRunState(failed->id, RunState::kFailed, "x").ok());
  auto open = sessions.ListUnfinishedRuns();
  ASSERT_TRUE(open.ok()) << open.status().ToString();
  ASSERT_EQ(open->size(), 2u);
  EXPECT_EQ((*open)[0].id, queued->id);
  EXPECT_EQ((*open)[1].id, running->id);
  EXPECT_EQ((*open)[1].state, RunState::kRunning);
}

}  // namespace
}  // namespace fesbench::storage::testing
