#include "api/run_start.h"

#include <gtest/gtest.h>

namespace fesbench::api {
namespace {

using nlohmann::json;

TEST(StartRunRequest, RoundTripsNumbersChoicesAndATarget) {
  StartRunRequest request{.protocol = "tracking",
                          .parameters = {{"duration_s", 30.0}, {"parameter_set_id", 4.0}},
                          .choices = {{"target", "uploaded"}, {"controller", "pid"}},
                          .ceiling_reason = std::nullopt,
                          .target = TargetSamples{{0.0, 0.5, 1.0}, {40.0, 45.0, 50.0}}};
  const json j = StartRunRequestToJson(request);
  EXPECT_EQ(j["parameters"]["target"], "uploaded");
  EXPECT_EQ(j["parameters"]["duration_s"], 30.0);
  const Result<StartRunRequest> back = StartRunRequestFromJson(j);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->protocol, "tracking");
  EXPECT_EQ(back->parameters, request.parameters);
  EXPECT_EQ(back->choices, request.choices);
  EXPECT_FALSE(back->ceiling_reason.has_value());
  ASSERT_TRUE(back->target.has_value());
  EXPECT_EQ(back->target->angle_deg, request.target->angle_deg);
}

TEST(StartRunRequest, NamesTheFieldOfAMalformedRequest) {
  const auto field = [](const json& body) {
    return StartRunRequestFromJson(body).status().field();
  };
  EXPECT_EQ(field(json::object()), "protocol");
  EXPECT_EQ(field({{"protocol", "x"}, {"parameters", {{"amplitude_ma", true}}}}),
            "parameters.amplitude_ma");
  EXPECT_EQ(field({{"protocol", "x"}, {"target_samples", {{"t_s", {0, 1}}}}}),
            "target_samples.angle_deg");
  EXPECT_EQ(
      field({{"protocol", "x"}, {"target_samples", {{"t_s", {0, "1"}}, {"angle_deg", {1, 2}}}}}),
      "target_samples.t_s[1]");
  EXPECT_EQ(field({{"protocol", "x"}, {"ceiling_reason", std::string(501, 'a')}}),
            "ceiling_reason");
  EXPECT_EQ(field({{"protocol", "x"}, {"param", 1}}), "param");
  // A choice too long, and a choice after a parameter that already failed.
  EXPECT_EQ(field({{"protocol", "x"}, {"parameters", {{"controller", std::string(65, 'p')}}}}),
            "parameters.controller");
  EXPECT_EQ(field({{"protocol", "x"}, {"parameters", {{"a", true}, {"b", "pid"}}}}),
            "parameters.a");
  json many = json::object();
  for (int i = 0; i <= static_cast<int>(kMaxRunParameters); ++i) many["p" + std::to_string(i)] = i;
  EXPECT_EQ(field({{"protocol", "x"}, {"parameters", many}}), "parameters");
}

}  // namespace
}  // namespace fesbench::api
