#include "server/services/job_pool.h"

#include <gtest/gtest.h>

#include <future>
#include <stdexcept>
#include <thread>

namespace fesbench::server::services {
namespace {

const Actor kAnalyst{7, "ana", Role::kAnalyst};

JobPoolConfig OneWorker(std::size_t capacity) {
  JobPoolConfig c;
  c.workers = 1;
  c.queue_capacity = capacity;
  return c;
}

TEST(JobPool, RunsJobAndRecordsResultAndTimes) {
  JobPool pool;
  auto id = pool.Submit("identification", kAnalyst, [] {
    return api::Result<nlohmann::json>(nlohmann::json{{"x", 2}});
  });
  ASSERT_TRUE(id.ok()) << id.status().ToString();
  pool.Shutdown(/*drain=*/true);
  auto job = pool.Get(*id);
  ASSERT_TRUE(job.ok());
  EXPECT_EQ(job->state, JobState::kDone);
  EXPECT_EQ(job->result["x"], 2);
  EXPECT_EQ(job->kind, "identification");
  EXPECT_EQ(job->actor.user_name, "ana");
  ASSERT_TRUE(job->started_at && job->finished_at);
  EXPECT_LE(job->submitted_at, *job->started_at);
  EXPECT_LE(*job->started_at, *job->finished_at);
  const nlohmann::json j = JobToJson(*job);
  EXPECT_EQ(j["state"], "done");
  EXPECT_EQ(j["result"]["x"], 2);
  EXPECT_EQ(j["submitted_by"]["role"], "analyst");
}

TEST(JobPool, FailingJobRecordsItsStatus) {
  JobPool pool;
  auto failing = pool.Submit("prediction", kAnalyst, [] {
    return api::Result<nlohmann::json>(api::Status::InvalidArgument("too long", "duration_s"));
  });
  auto throwing = pool.Submit("prediction", kAnalyst, []() -> api::Result<nlohmann::json> {
    throw std::runtime_error("diverged");
  });
  ASSERT_TRUE(failing.ok() && throwing.ok());
  pool.Shutdown(true);
  auto f = pool.Get(*failing);
  ASSERT_TRUE(f.ok());
  EXPECT_EQ(f->state, JobState::kFailed);
  EXPECT_EQ(f->error.code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(f->error.field(), "duration_s");
  EXPECT_EQ(JobToJson(*f)["error"]["code"], "invalid_argument");
  auto t = pool.Get(*throwing);
  ASSERT_TRUE(t.ok());
  EXPECT_EQ(t->state, JobState::kFailed);
  EXPECT_EQ(t->error.code(), api::ErrorCode::kInternal);
  EXPECT_NE(t->error.message().find("diverged"), std::string::npos);
}

TEST(JobPool, FullQueueIsUnavailableAndShutdownCancelsQueued) {
  JobPool pool(OneWorker(1));
  std::promise<void> started, release;
  std::shared_future<void> gate = release.get_future().share();
  auto running = pool.Submit("identification", kAnalyst, [&started, gate] {
    started.set_value();
    gate.wait();
    return api::Result<nlohmann::json>(nlohmann::json(1));
  });
  ASSERT_TRUE(running.ok());
  started.get_future().wait();  // the worker is busy: the next job waits in the queue
  auto queued = pool.Submit("identification", kAnalyst,
                            [] { return api::Result<nlohmann::json>(nlohmann::json(2)); });
  ASSERT_TRUE(queued.ok());
  EXPECT_EQ(pool.queued(), 1u);
  EXPECT_EQ(pool.Get(*queued)->state, JobState::kQueued);
  EXPECT_EQ(pool.Get(*running)->state, JobState::kRunning);
  auto full = pool.Submit("identification", kAnalyst,
                          [] { return api::Result<nlohmann::json>(nlohmann::json(3)); });
  ASSERT_FALSE(full.ok());
  EXPECT_EQ(full.status().code(), api::ErrorCode::kUnavailable);
  EXPECT_NE(full.status().message().find("job queue full"), std::string::npos);

  // Shut down while the first job runs; release it once the queued one is cancelled.
  std::thread stopper([&pool] { pool.Shutdown(/*drain=*/false); });
  while (pool.Get(*queued)->state == JobState::kQueued) std::this_thread::yield();
  release.set_value();
  stopper.join();
  EXPECT_EQ(pool.Get(*running)->state, JobState::kDone);  // running jobs finish
  auto cancelled = pool.Get(*queued);
  EXPECT_EQ(cancelled->state, JobState::kFailed);
  EXPECT_EQ(cancelled->error.code(), api::ErrorCode::kUnavailable);
  auto after = pool.Submit("identification", kAnalyst,
                           [] { return api::Result<nlohmann::json>(nlohmann::json(4)); });
  EXPECT_EQ(after.status().code(), api::ErrorCode::kUnavailable);
}

TEST(JobPool, UnknownIdIsNotFoundAndListIsNewestFirst) {
  JobPool pool;
  EXPECT_EQ(pool.Get(42).status().code(), api::ErrorCode::kNotFound);
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(pool.Submit("comparison", kAnalyst,
                            [i] { return api::Result<nlohmann::json>(nlohmann::json(i)); })
                    .ok());
  }
  pool.Shutdown(true);
  const auto list = pool.List(2);
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0].id, 3);
  EXPECT_EQ(list[1].id, 2);
  EXPECT_EQ(pool.Submit("", kAnalyst, [] { return api::Result<nlohmann::json>(nlohmann::json()); })
                .status()
                .field(),
            "kind");
}

TEST(JobPool, ForgetsOldestFinishedBeyondHistory) {
  JobPoolConfig c;
  c.history = 2;
  c.workers = 1;  // jobs finish in submission order, so "oldest" is well defined
  JobPool pool(c);
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(
        pool.Submit("k", kAnalyst, [] { return api::Result<nlohmann::json>(nlohmann::json()); })
            .ok());
  }
  pool.Shutdown(true);
  EXPECT_EQ(pool.Get(1).status().code(), api::ErrorCode::kNotFound);
  EXPECT_EQ(pool.Get(2).status().code(), api::ErrorCode::kNotFound);
  EXPECT_TRUE(pool.Get(4).ok());
}

TEST(JobPool, ApproximateJsonBytesCountsNodesStringsAndContainers) {
  EXPECT_EQ(ApproximateJsonBytes(nlohmann::json(1.5)), sizeof(nlohmann::json));
  EXPECT_EQ(ApproximateJsonBytes(nlohmann::json("abc")),
            sizeof(nlohmann::json) + sizeof(std::string) + 3);
  const nlohmann::json column(std::vector<double>(1000, 0.5));
  EXPECT_EQ(ApproximateJsonBytes(column), sizeof(nlohmann::json) + sizeof(nlohmann::json::array_t) +
                                              1000 * sizeof(nlohmann::json));
  const nlohmann::json object = {{"t_s", column}};
  EXPECT_EQ(ApproximateJsonBytes(object), sizeof(nlohmann::json) +
                                              sizeof(nlohmann::json::object_t) + 48 + 3 +
                                              ApproximateJsonBytes(column));
}

// Big results (a prediction's columns) are bounded by bytes, not only by
// count: the oldest go first, the newest always stays.
TEST(JobPool, ForgetsOldestFinishedBeyondHistoryBytes) {
  JobPoolConfig c;
  c.history = 1000;
  c.history_bytes = 100'000;
  c.workers = 1;
  JobPool pool(c);
  const auto big = [] {  // ≈ 40 kB
    return api::Result<nlohmann::json>(nlohmann::json{{"columns", std::vector<double>(2500, 1.0)}});
  };
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(pool.Submit("prediction", kAnalyst, big).ok());
  pool.Shutdown(true);
  const std::size_t one = ApproximateJsonBytes(*big());
  ASSERT_GT(one, 30'000u);
  ASSERT_LT(one, 50'000u);
  const int kept = static_cast<int>(c.history_bytes / one);  // 2
  for (int id = 1; id <= 5; ++id) {
    EXPECT_EQ(pool.Get(id).ok(), id > 5 - kept) << "job " << id;
  }
  EXPECT_EQ(pool.Get(5)->result_bytes, one);

  JobPoolConfig tiny = c;
  tiny.history_bytes = 1;  // smaller than any result: the newest still stays
  JobPool keeps_newest(tiny);
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(keeps_newest.Submit("prediction", kAnalyst, big).ok());
  keeps_newest.Shutdown(true);
  EXPECT_FALSE(keeps_newest.Get(2).ok());
  EXPECT_TRUE(keeps_newest.Get(3).ok());
}

}  // namespace
}  // namespace fesbench::server::services
