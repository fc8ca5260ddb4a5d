#include "api/status.h"

#include <gtest/gtest.h>

namespace fesbench::api {
namespace {

TEST(Status, DescribesCodeFieldAndMessage) {
  EXPECT_TRUE(Status().ok());
  const Status s = Status::InvalidArgument("must be positive", "passive.inertia_kgm2");
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(s.ToString(), "invalid_argument: passive.inertia_kgm2: must be positive");
  EXPECT_EQ(Status::NotFound("no subject 7").ToString(), "not_found: no subject 7");
}

TEST(Result, HoldsValueOrStatus) {
  Result<int> good = 3;
  ASSERT_TRUE(good.ok());
  EXPECT_EQ(*good, 3);
  EXPECT_TRUE(good.status().ok());
  Result<int> bad = Status::Conflict("bench busy");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), ErrorCode::kConflict);
}

}  // namespace
}  // namespace fesbench::api
