// Strict reading of JSON request bodies (api/json_fields.h).

#include "api/json_fields.h"

#include <gtest/gtest.h>

#include <string>

namespace fesbench::api {
namespace {

using nlohmann::json;

TEST(JsonFieldsTest, ReadsStrictlyWithFieldPaths) {
  json body = {{"name", "x"},  {"n", 3},        {"f", 2.5},
               {"flag", true}, {"ids", {1, 2}}, {"inner", {{"a", 1}}}};
  JsonFields f(body);
  EXPECT_EQ(f.String("name", true), "x");
  EXPECT_EQ(f.Integer("n", true, 0, 10), 3);
  EXPECT_EQ(f.Number("f", true, 0, 10), 2.5);
  EXPECT_EQ(f.Bool("flag", true), true);
  EXPECT_EQ(f.IdList("ids", true), (std::vector<std::int64_t>{1, 2}));
  EXPECT_NE(f.Object("inner", true), nullptr);
  EXPECT_TRUE(f.Finish().ok());

  auto first_error = [](json j, auto read) {
    JsonFields f(j, "outer");
    read(f);
    return f.Finish();
  };
  auto st = first_error({{"n", "3"}}, [](JsonFields& f) { (void)f.Integer("n", true); });
  EXPECT_EQ(st.code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(st.field(), "outer.n");
  st = first_error({{"n", 2.5}}, [](JsonFields& f) { (void)f.Integer("n", true); });
  EXPECT_EQ(st.field(), "outer.n");
  st = first_error(json::object(), [](JsonFields& f) { (void)f.String("s", true); });
  EXPECT_EQ(st.field(), "outer.s");
  EXPECT_NE(st.message().find("required"), std::string::npos);
  st = first_error({{"x", 11}}, [](JsonFields& f) { (void)f.Number("x", true, 0, 10); });
  EXPECT_EQ(st.field(), "outer.x");
  st = first_error({{"x", 1}, {"typo", 2}}, [](JsonFields& f) { (void)f.Number("x", true); });
  EXPECT_EQ(st.field(), "outer.typo");
  st = first_error({{"ids", {1, -2}}}, [](JsonFields& f) { (void)f.IdList("ids", true); });
  EXPECT_EQ(st.field(), "outer.ids[1]");
  st = first_error({{"s", std::string(20, 'a')}},
                   [](JsonFields& f) { (void)f.String("s", true, 10); });
  EXPECT_EQ(st.field(), "outer.s");
  // null counts as absent.
  st = first_error({{"s", nullptr}}, [](JsonFields& f) { EXPECT_FALSE(f.String("s", false)); });
  EXPECT_TRUE(st.ok());
}

TEST(JsonFieldsTest, ParseRefusesMalformedDeepAndNonObjects) {
  EXPECT_TRUE(ParseJsonObject("{\"a\": [1, {\"b\": \"[[[\"}]}").ok());
  EXPECT_FALSE(ParseJsonObject("").ok());
  EXPECT_FALSE(ParseJsonObject("{").ok());
  EXPECT_FALSE(ParseJsonObject("[]").ok());
  EXPECT_FALSE(ParseJsonObject("{\"a\": NaN}").ok());
  std::string deep =
      "{\"a\":" + std::string(kMaxJsonDepth, '[') + std::string(kMaxJsonDepth, ']') + "}";
  auto r = ParseJsonObject(deep);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("nested"), std::string::npos);
  std::string shallow =
      "{\"a\":" + std::string(kMaxJsonDepth - 1, '[') + std::string(kMaxJsonDepth - 1, ']') + "}";
  EXPECT_TRUE(ParseJsonObject(shallow).ok());
}

TEST(JsonFieldsTest, ParseRefusesAKeyTwiceNamingItsPath) {
  const auto field_of = [](std::string_view text) {
    auto r = ParseJsonObject(text);
    EXPECT_FALSE(r.ok()) << text;
    if (r.ok()) return std::string("(accepted)");
    EXPECT_EQ(r.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("duplicate key"), std::string::npos);
    return r.status().field();
  };
  EXPECT_EQ(field_of(R"({"code": "S1", "code": "S2"})"), "code");
  EXPECT_EQ(field_of(R"({"details": {"height_cm": 170, "weight_kg": 70, "height_cm": 180}})"),
            "details.height_cm");
  EXPECT_EQ(field_of(R"({"pairs": [{"a": 1}, {"b": 1, "b": 2}]})"), "pairs[1].b");
  // The same key in different objects, or as a value, is no repetition.
  EXPECT_TRUE(ParseJsonObject(R"({"a": {"a": "a"}, "b": [{"a": 1}, {"a": 2}]})").ok());
}

TEST(JsonFieldsTest, ParseRefusesMoreValuesThanTheReaderExpects) {
  EXPECT_TRUE(ParseJsonObject(R"({"a": [1, 2, 3]})", {.max_values = 5}).ok());
  auto r = ParseJsonObject(R"({"a": [1, 2, 3, 4, 5]})", {.max_values = 5});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("more than 5 JSON values"), std::string::npos);
  EXPECT_EQ(r.status().field(), "a[3]");
}

}  // namespace
}  // namespace fesbench::api
