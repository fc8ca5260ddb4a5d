#include "storage/connection.h"

#include <gtest/gtest.h>

#include <vector>

namespace fesbench::storage {
namespace {

TEST(Samples, PackIsLittleEndianFloat64) {
  const std::vector<double> values = {1.0, -2.5};
  const auto blob = PackFloat64Le(values);
  ASSERT_EQ(blob.size(), 16u);
  // 1.0 = 0x3FF0000000000000: least significant byte first.
  EXPECT_EQ(blob[0], std::byte{0x00});
  EXPECT_EQ(blob[7], std::byte{0x3F});
  EXPECT_EQ(blob[6], std::byte{0xF0});
  auto back = UnpackFloat64Le(blob);
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(*back, values);
  EXPECT_FALSE(UnpackFloat64Le(std::span(blob).first(9)).has_value());
}

}  // namespace
}  // namespace fesbench::storage
