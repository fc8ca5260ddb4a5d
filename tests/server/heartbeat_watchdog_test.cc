#include "server/safety/heartbeat_watchdog.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>
#include <vector>

#include "tests/support/manual_clock.h"

namespace fesbench::server {
namespace {

TEST(HeartbeatWatchdog, UnarmedNeverTrips) {
  ::fesbench::testing::ManualClock clock;
  HeartbeatWatchdog watchdog(&clock);
  clock.Advance(100.0);
  EXPECT_FALSE(watchdog.Check(1.0));
  EXPECT_FALSE(watchdog.fired());
}

TEST(HeartbeatWatchdog, TripsOnceWhenTheClientFallsSilentForLongerThanTheTimeout) {
  ::fesbench::testing::ManualClock clock(50.0);
  HeartbeatWatchdog watchdog(&clock);
  watchdog.Arm();  // arming counts as a beat
  clock.Advance(0.9);
  EXPECT_FALSE(watchdog.Check(1.0));
  watchdog.Beat();
  clock.Advance(1.0);  // exactly the timeout: not more than it
  EXPECT_FALSE(watchdog.Check(1.0));
  clock.Advance(0.25);
  const std::optional<double> silent = watchdog.Check(1.0);
  ASSERT_TRUE(silent);
  EXPECT_NEAR(*silent, 1.25, 1e-12);
  EXPECT_TRUE(watchdog.fired());
  EXPECT_FALSE(watchdog.Check(1.0));  // reported once
  watchdog.Beat();                    // a late beat does not undo the trip
  EXPECT_TRUE(watchdog.fired());
}

TEST(HeartbeatWatchdog, ArmClearsATripAndDisarmStopsWatching) {
  ::fesbench::testing::ManualClock clock;
  HeartbeatWatchdog watchdog(&clock);
  watchdog.Arm();
  clock.Advance(2.0);
  ASSERT_TRUE(watchdog.Check(1.0));
  watchdog.Disarm();
  EXPECT_TRUE(watchdog.fired());  // visible until the next run arms it
  watchdog.Arm();
  EXPECT_FALSE(watchdog.fired());
  watchdog.Disarm();
  clock.Advance(10.0);
  EXPECT_FALSE(watchdog.Check(1.0));
}

TEST(HeartbeatWatchdog, ConcurrentCheckersReportOneTrip) {
  ::fesbench::testing::ManualClock clock;
  HeartbeatWatchdog watchdog(&clock);
  watchdog.Arm();
  clock.Advance(5.0);
  std::atomic<int> trips{0};
  std::vector<std::thread> threads;
  for (int i = 0; i < 4; ++i) {
    threads.emplace_back([&] {
      for (int k = 0; k < 1000; ++k) {
        if (watchdog.Check(1.0)) ++trips;
      }
    });
  }
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(trips.load(), 1);
}

}  // namespace
}  // namespace fesbench::server
