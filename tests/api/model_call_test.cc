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
  // A computation that could not finish, and a refusal the caller names.
  const Status diverged =
      CallModel([] { throw std::runtime_error("Dormand-Prince 5(4): non-finite state"); });
  EXPECT_EQ(diverged.code(), ErrorCode::kFailedPrecondition);
  EXPECT_EQ(diverged.message(), "Dormand-Prince 5(4): non-finite state");
  const Status refused = CallModel([] { throw std::invalid_argument("too few samples"); }, "",
                                   ErrorCode::kFailedPrecondition);
  EXPECT_EQ(refused.code(), ErrorCode::kFailedPrecondition);
  // A caller's own exception thrown through the call is not the model's.
  struct UsageError : std::runtime_error {
    using std::runtime_error::runtime_error;
  };
  EXPECT_THROW((void)CallModel([] { throw UsageError("--option: expected k=v"); }), UsageError);
}

}  // namespace
}  // namespace fesbench::api
