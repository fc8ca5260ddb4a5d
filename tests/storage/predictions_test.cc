#include "storage/predictions.h"

#include <gtest/gtest.h>

#include <limits>

#include "storage/parameter_sets.h"
#include "storage/trials.h"
#include "storage_test_util.h"

namespace fesbench::storage {
namespace {

using testing::MakeTrial;
using testing::StorageTest;

TEST_P(StorageTest, PredictionsAndEvaluations) {
  const Session session = MakeSession("E1");
  auto trial = TrialRepository(*db_).Insert({session.id, std::nullopt}, MakeTrial(10));
  ASSERT_TRUE(trial.ok());
  ParameterSetRepository sets(*db_);
  auto set = sets.Insert({session.subject_id, session.leg_id, model::ExampleParameterSet(),
                          std::nullopt, std::nullopt});
  ASSERT_TRUE(set.ok());
  PredictionRepository repo(*db_);
  auto prediction = repo.InsertPrediction(
      {set->id, *trial, R"({"stimulus": "replay"})", R"({"angle_deg": [1, 2]})"});
  ASSERT_TRUE(prediction.ok()) << prediction.status().ToString();
  EXPECT_EQ(prediction->prediction.trial_id, *trial);
  auto evaluation = repo.InsertEvaluation(
      {set->id, *trial, prediction->id, "angle_deg", "deg", 2.75, 6.5, R"({"r2": 0.93})"});
  ASSERT_TRUE(evaluation.ok()) << evaluation.status().ToString();
  auto got = repo.GetEvaluation(evaluation->id);
  ASSERT_TRUE(got.ok());
  EXPECT_EQ(got->evaluation.rms_error, 2.75);
  EXPECT_EQ(got->evaluation.max_abs_error, 6.5);
  EXPECT_EQ(got->evaluation.details_json, R"({"r2": 0.93})");
  auto listed = repo.EvaluationsFor(set->id);
  ASSERT_TRUE(listed.ok());
  EXPECT_EQ(listed->size(), 1u);
  auto predictions = repo.PredictionsFor(set->id);
  ASSERT_TRUE(predictions.ok());
  ASSERT_EQ(predictions->size(), 1u);
  EXPECT_EQ(predictions->front().prediction.output_json, R"({"angle_deg": [1, 2]})");

  // Bad input.
  EXPECT_EQ(repo.InsertPrediction({999, std::nullopt, "{}", "{}"}).status().field(),
            "parameter_set_id");
  EXPECT_EQ(repo.InsertPrediction({set->id, 999, "{}", "{}"}).status().field(), "trial_id");
  EXPECT_EQ(repo.InsertPrediction({set->id, std::nullopt, "{", "{}"}).status().field(),
            "input_json");
  EXPECT_EQ(repo.InsertEvaluation({set->id, *trial, std::nullopt, "angle_deg", "deg", -1, 0, "{}"})
                .status()
                .field(),
            "rms_error");
  EXPECT_EQ(repo.InsertEvaluation({set->id, *trial, std::nullopt, "angle_deg", "deg", 1,
                                   std::numeric_limits<double>::quiet_NaN(), "{}"})
                .status()
                .field(),
            "max_abs_error");
  EXPECT_EQ(
      repo.InsertEvaluation({set->id, *trial, 999, "angle_deg", "deg", 1, 1, "{}"}).status().code(),
      api::ErrorCode::kNotFound);
  EXPECT_EQ(repo.GetPrediction(999).status().message(), "prediction 999 not found");
}

}  // namespace
}  // namespace fesbench::storage
