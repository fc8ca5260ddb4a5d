#include "api/model_call.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

namespace fesbench::api {
namespace {

TEST(CallModel, ReturnsTheValue) {
  const Result<double> r = CallModel([] { return 2.5; });
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(*r, 2.5);
  EXPECT_TRUE(CallModel([] {}).ok());
}

TEST(CallModel, MakesTheModelsInvalidArgumentAStatusWithItsMessage) {
  const Result<int> r =
      CallModel([]() -> int { throw std::invalid_argument("needs at least 2 samples"); }, "trial");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(r.status().message(), "needs at least 2 samples");
  EXPECT_EQ(r.status().field(), "trial");
  const Status v = CallModel([] { throw std::invalid_argument("J must be positive"); });
  EXPECT_EQ(v.ToString(), "invalid_argument: J must be positive");
}

TEST(CallModel, LetsAnyOtherExceptionThrough) {
  EXPECT_THROW((void)CallModel([]() -> int { throw std::logic_error("a bug"); }), std::logic_error);
}

}  // namespace
}  // namespace fesbench::api
