#include "storage/export.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "api/trial.h"
#include "storage/parameter_sets.h"
#include "storage/trials.h"
#include "storage_test_util.h"

namespace fesbench::storage {
namespace {

using testing::MakeTrial;
using testing::StorageTest;

TEST_P(StorageTest, ExportsTrialAsCsvAndStoAndParameterSetAsJson) {
  const Session session = MakeSession("X1");
  const api::Trial trial = MakeTrial(3);
  auto id = TrialRepository(*db_).Insert({session.id, std::nullopt}, trial);
  ASSERT_TRUE(id.ok());

  auto csv = ExportTrialCsv(*db_, *id);
  ASSERT_TRUE(csv.ok());
  EXPECT_EQ(csv->substr(0, csv->find('\n')), "t_s,angle_deg,torque_nm,stim_ma");
  auto reread = api::TrialFromCsv(*csv);
  ASSERT_TRUE(reread.ok());
  EXPECT_EQ(reread->channels, trial.channels);  // exact round trip

  auto sto = ExportTrialSto(*db_, *id);
  ASSERT_TRUE(sto.ok());
  EXPECT_EQ(sto->substr(0, sto->find('\n')), "free_swing");
  EXPECT_NE(sto->find("nRows=3\n"), std::string::npos);
  EXPECT_NE(sto->find("nColumns=4\n"), std::string::npos);
  EXPECT_NE(sto->find("endheader\ntime\tangle_deg\ttorque_nm\tstim_ma\n"), std::string::npos);

  auto set = ParameterSetRepository(*db_).Insert({session.subject_id, session.leg_id,
                                                  model::ExampleParameterSet(), std::nullopt,
                                                  std::nullopt});
  ASSERT_TRUE(set.ok());
  auto json = ExportParameterSetJson(*db_, set->id);
  ASSERT_TRUE(json.ok());
  const auto parsed = nlohmann::json::parse(*json);
  EXPECT_EQ(parsed.at("model"), "full");
  EXPECT_EQ(parsed.at("contraction").at("pole_per_s"), 25.0);

  EXPECT_EQ(ExportTrialCsv(*db_, 999).status().code(), api::ErrorCode::kNotFound);
  EXPECT_EQ(ExportTrialSto(*db_, 999).status().code(), api::ErrorCode::kNotFound);
  EXPECT_EQ(ExportParameterSetJson(*db_, 999).status().code(), api::ErrorCode::kNotFound);
}

}  // namespace
}  // namespace fesbench::storage
