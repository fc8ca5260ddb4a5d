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

}  // namespace
}  // namespace fesbench::server::services
