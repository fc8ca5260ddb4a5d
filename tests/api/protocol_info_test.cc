#include "api/protocol_info.h"

#include <gtest/gtest.h>

namespace fesbench::api {
namespace {

using nlohmann::json;

TEST(ProtocolInfo, ReadsBackWhatItWrote) {
  ProtocolInfo info{.name = "tolerance_test",
                    .version = 2,
                    .title = "Tolerance test",
                    .description = "a slow ramp",
                    .thesis_section = "Appendix F",
                    .stimulates = true,
                    .bench_mode = "locked",
                    .min_rest_s = 60.0,
                    .measures_max_tolerated = true,
                    .follows_target = false,
                    .offered_first = true};
  info.parameters.push_back({.name = "ceiling_ma",
                             .label = "Ceiling",
                             .unit = "mA",
                             .description = "highest amplitude",
                             .default_value = std::nullopt,
                             .default_rule = "the session's max tolerated amplitude",
                             .min = 0.0,
                             .max = 100.0,
                             .integer = false,
                             .advanced = false,
                             .scales_to = "tolerance_ceiling",
                             .rest = false,
                             .choices = {}});
  info.parameters.push_back({.name = "target",
                             .label = "Target",
                             .unit = "1",
                             .description = "",
                             .default_value = 0.0,
                             .default_rule = std::nullopt,
                             .min = 0.0,
                             .max = 1.0,
                             .integer = true,
                             .advanced = true,
                             .scales_to = "none",
                             .rest = false,
                             .choices = {"sine", "uploaded"}});
  const json j = ProtocolInfoToJson(info);
  EXPECT_TRUE(j["parameters"][0]["default"].is_null());
  EXPECT_TRUE(j["parameters"][1]["default_rule"].is_null());

  const Result<ProtocolInfo> back = ProtocolInfoFromJson(j);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->name, "tolerance_test");
  EXPECT_EQ(back->version, 2);
  EXPECT_EQ(back->thesis_section, "Appendix F");
  EXPECT_EQ(back->bench_mode, "locked");
  EXPECT_EQ(back->min_rest_s, 60.0);
  EXPECT_TRUE(back->measures_max_tolerated);
  EXPECT_FALSE(back->follows_target);
  EXPECT_TRUE(back->offered_first);
  ASSERT_EQ(back->parameters.size(), 2u);
  EXPECT_FALSE(back->parameters[0].default_value.has_value());
  EXPECT_EQ(back->parameters[0].default_rule, info.parameters[0].default_rule);
  EXPECT_EQ(back->parameters[0].scales_to, "tolerance_ceiling");
  EXPECT_EQ(back->parameters[1].default_value, 0.0);
  EXPECT_TRUE(back->parameters[1].integer);
  EXPECT_TRUE(back->parameters[1].advanced);
  EXPECT_EQ(back->parameters[1].choices, (std::vector<std::string>{"sine", "uploaded"}));
}

TEST(ProtocolInfo, NamesTheFieldItCannotRead) {
  json j = ProtocolInfoToJson(ProtocolInfo{.name = "x", .parameters = {{.name = "a_ma"}}});
  j["parameters"][0]["max"] = "lots";
  EXPECT_EQ(ProtocolInfoFromJson(j).status().field(), "parameters[0].max");
  j = ProtocolInfoToJson(ProtocolInfo{.name = "x"});
  j.erase("name");
  EXPECT_EQ(ProtocolInfoFromJson(j).status().field(), "name");
  j = ProtocolInfoToJson(ProtocolInfo{.name = "x"});
  j["parameters"] = 3;
  EXPECT_EQ(ProtocolInfoFromJson(j).status().field(), "parameters");
  j = ProtocolInfoToJson(ProtocolInfo{.name = "x"});
  j["from_a_newer_server"] = true;
  EXPECT_TRUE(ProtocolInfoFromJson(j).ok());
}

}  // namespace
}  // namespace fesbench::api
