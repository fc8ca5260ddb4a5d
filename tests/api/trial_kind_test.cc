// The typed trial kind (api/trial_kind.h): names, families, the
// properties clients select trials by, and the kind on the trial's JSON.

#include "api/trial_kind.h"

#include <gtest/gtest.h>

#include "api/trial.h"

namespace fesbench::api {
namespace {

TEST(TrialKind, EveryKindHasOneRowAndItsNameParsesBack) {
  for (const TrialKindInfo& info : TrialKinds()) {
    EXPECT_EQ(&InfoOf(info.kind), &info) << info.name;
    EXPECT_EQ(TrialKindName(info.kind), info.name);
    EXPECT_EQ(ParseTrialKind(info.name), info.kind) << info.name;
    EXPECT_EQ(TrialKindOf(info.name), info.kind) << info.name;
  }
  // A member of a family belongs to the family but is not a kind's name.
  EXPECT_EQ(TrialKindOf("passive_simultaneous_3"), TrialKind::kPassiveSimultaneous);
  EXPECT_EQ(ParseTrialKind("passive_simultaneous_3"), std::nullopt);
  // The longest stem wins: "prediction_random_binary" over nothing shorter.
  EXPECT_EQ(TrialKindOf("prediction_random_binary_s4"), TrialKind::kPredictionRandomBinary);
  EXPECT_EQ(TrialKindOf("active_"), std::nullopt);
  EXPECT_EQ(TrialKindOf("Active_RB1"), std::nullopt);
}

TEST(TrialKind, FreeSwingAndValidationFollowTheTable) {
  // Free swing: the knee moves under stimulation alone.
  EXPECT_TRUE(IsFreeSwing(TrialKind::kFreeSwingPassive));
  EXPECT_TRUE(IsFreeSwing(TrialKind::kActive));
  EXPECT_TRUE(IsFreeSwing(TrialKind::kPredictionStep));
  EXPECT_TRUE(IsFreeSwing(TrialKind::kRapidActive));
  EXPECT_FALSE(IsFreeSwing(TrialKind::kToleranceTest));
  EXPECT_FALSE(IsFreeSwing(TrialKind::kRampIrc));              // knee locked
  EXPECT_FALSE(IsFreeSwing(TrialKind::kIsometricPrediction));  // knee locked
  EXPECT_FALSE(IsFreeSwing(TrialKind::kPassivePositions));     // the motor moves it
  // Validation: the prediction protocols' trials, and nothing else (the
  // server's protocol_test checks which protocol records each).
  const std::vector<TrialKind> expected = {
      TrialKind::kIsometricPrediction, TrialKind::kPredictionRandomBinary,
      TrialKind::kPredictionStep, TrialKind::kPredictionRamp, TrialKind::kPredictionSine};
  std::vector<TrialKind> validation;
  for (const TrialKindInfo& info : TrialKinds()) {
    if (IsValidation(info.kind)) validation.push_back(info.kind);
  }
  EXPECT_EQ(validation, expected);
}

TEST(TrialKind, TheTrialJsonCarriesTheKindAndRefusesAWrongOne) {
  Trial trial;
  trial.name = "active_random_binary_rb1";
  trial.kind = TrialKind::kActive;
  trial.SetChannel("t_s", {0.0, 0.005});
  trial.SetChannel("stim_ma", {0.0, 1.0});
  nlohmann::json json = TrialToJson(trial);
  EXPECT_EQ(json["kind"], "active_random_binary");
  Result<Trial> back = TrialFromJson(json);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(*back, trial);

  json["kind"] = "free_swing_passive";  // not the name's kind
  Result<Trial> wrong = TrialFromJson(json);
  ASSERT_FALSE(wrong.ok());
  EXPECT_EQ(wrong.status().field(), "kind");
  json["kind"] = "active_random_binary_rb1";  // a member's name, not a kind
  Result<Trial> unknown = TrialFromJson(json);
  ASSERT_FALSE(unknown.ok());
  EXPECT_EQ(unknown.status().field(), "kind");
  EXPECT_NE(unknown.status().message().find("active_random_binary_rb1"), std::string::npos);
}

}  // namespace
}  // namespace fesbench::api
