// The one clock interface (api/clock.h): the process's clock.

#include "api/clock.h"

#include <gtest/gtest.h>

#include <chrono>

namespace fesbench::api {
namespace {

TEST(Clock, TheRealClockIsMonotonicSleepsAndTellsUtc) {
  Clock* clock = Clock::Real();
  ASSERT_NE(clock, nullptr);
  EXPECT_EQ(clock, Clock::Real());  // one clock for the process
  const double t0 = clock->MonotonicSeconds();
  clock->SleepFor(0.002);
  const double t1 = clock->MonotonicSeconds();
  EXPECT_GE(t1 - t0, 0.002);
  clock->SleepFor(-1.0);  // returns at once
  EXPECT_GE(clock->MonotonicSeconds(), t1);
  const auto system = std::chrono::system_clock::now();
  const UtcTime utc = clock->UtcNow();
  EXPECT_LT(std::chrono::abs(std::chrono::duration_cast<std::chrono::milliseconds>(utc - system)),
            std::chrono::seconds(5));
}

}  // namespace
}  // namespace fesbench::api
