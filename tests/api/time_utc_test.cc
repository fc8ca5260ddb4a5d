#include "api/time_utc.h"

#include <gtest/gtest.h>

namespace fesbench::api {
namespace {

TEST(TimeUtc, FormatsAndParsesMicroseconds) {
  const UtcTime t = std::chrono::sys_days{std::chrono::year{2026} / 11 / 21} +
                    std::chrono::hours(10) + std::chrono::minutes(36) + std::chrono::seconds(43) +
                    std::chrono::microseconds(123456);
  EXPECT_EQ(FormatUtc(t), "2026-11-21T10:36:43.123456Z");
  auto back = ParseUtc("2026-11-21T10:36:43.123456Z");
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(*back, t);
  EXPECT_FALSE(ParseUtc("2026-02-30T00:00:00.000000Z").has_value());
  EXPECT_FALSE(ParseUtc("2026-11-21 10:36:43Z").has_value());
  EXPECT_TRUE(IsIsoDate("2024-02-29"));
  EXPECT_FALSE(IsIsoDate("2023-02-29"));
  EXPECT_FALSE(IsIsoDate("2023-2-9"));
}

}  // namespace
}  // namespace fesbench::api
