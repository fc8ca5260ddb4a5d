#include "api/job.h"

#include <gtest/gtest.h>

namespace fesbench::api {
namespace {

using nlohmann::json;

TEST(Job, StatesRoundTripThroughTheirNames) {
  for (JobState state :
       {JobState::kQueued, JobState::kRunning, JobState::kDone, JobState::kFailed}) {
    EXPECT_EQ(ParseJobState(JobStateName(state)), state);
  }
  EXPECT_FALSE(ParseJobState("finished").has_value());
}

TEST(Job, ErrorCodesRoundTripThroughTheirNames) {
  for (int i = 0; i <= static_cast<int>(ErrorCode::kInternal); ++i) {
    const auto code = static_cast<ErrorCode>(i);
    EXPECT_EQ(ParseErrorCode(ErrorCodeName(code)), code);
  }
  EXPECT_FALSE(ParseErrorCode("teapot").has_value());
}

TEST(Job, AnErrorKeepsItsCodeMessageAndField) {
  const Status named = Status::InvalidArgument("must be positive", "trial_ids[0]");
  const json j = ErrorToJson(named);
  EXPECT_EQ(j["code"], "invalid_argument");
  EXPECT_EQ(j["field"], "trial_ids[0]");
  const Status back = ErrorFromJson(j);
  EXPECT_EQ(back.code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(back.message(), "must be positive");
  EXPECT_EQ(back.field(), "trial_ids[0]");

  EXPECT_FALSE(ErrorToJson(Status::NotFound("no set 9")).contains("field"));
  // Nothing a server sends reads as success.
  EXPECT_EQ(ErrorFromJson({{"code", "ok"}, {"message", "?"}}).code(), ErrorCode::kInternal);
  EXPECT_EQ(ErrorFromJson({{"code", "teapot"}}).code(), ErrorCode::kInternal);
  EXPECT_EQ(ErrorFromJson("broken").code(), ErrorCode::kInternal);
}

TEST(Job, ReportsReadTheResultOrTheError) {
  const Result<JobReport> done = JobReportFromJson(
      {{"id", 4}, {"kind", "prediction"}, {"state", "done"}, {"result", {{"x", 1}}}});
  ASSERT_TRUE(done.ok());
  EXPECT_EQ(done->id, 4);
  EXPECT_EQ(done->kind, "prediction");
  EXPECT_EQ(done->state, JobState::kDone);
  EXPECT_EQ(done->result["x"], 1);
  EXPECT_TRUE(done->error.ok());

  const Result<JobReport> failed = JobReportFromJson(
      {{"id", 5},
       {"state", "failed"},
       {"error", {{"code", "failed_precondition"}, {"message", "no rapid trials"}}}});
  ASSERT_TRUE(failed.ok());
  EXPECT_EQ(failed->error.code(), ErrorCode::kFailedPrecondition);
  EXPECT_EQ(failed->error.message(), "no rapid trials");
  EXPECT_TRUE(failed->result.is_null());

  EXPECT_EQ(JobReportFromJson({{"id", 5}, {"state", "lost"}}).status().field(), "state");
  EXPECT_EQ(JobReportFromJson({{"state", "done"}}).status().field(), "id");
}

}  // namespace
}  // namespace fesbench::api
