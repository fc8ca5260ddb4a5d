// Every protocol of the catalogue, run on the simulated bench at time scale
// 0, reads back from storage after a restart as it read while its server
// ran it (docs/ARCHITECTURE.md, "Runs": one stored outcome per run).

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "api/run.h"
#include "server/protocols/protocol.h"
#include "storage/audit_log.h"
#include "storage/parameter_sets.h"
#include "storage/trials.h"
#include "tests/server/run_service_rig.h"

namespace fesbench::server::services::test {
namespace {

// The fields only a view of the process that ran the run has: whether it is
// live, its controller, the safety layer's events, and the bench time it
// had run when the last progress event came (storage keeps the time at its
// end, bench_total_s).
const std::set<std::string> kLiveOnly = {"live", "controller", "safety_events",
                                         "bench_elapsed_s"};

nlohmann::json WithoutLiveOnly(nlohmann::json view) {
  for (const std::string& key : kLiveOnly) view.erase(key);
  return view;
}

// The order a session needs: the tolerance test records the limits, the
// rapid protocol the leg's approved set that daily_check, tracking and the
// prediction protocols use; then the catalogue in its order.
std::vector<std::string> ProtocolsInRunOrder() {
  std::vector<std::string> order = {"tolerance_test", "rapid_parameterisation"};
  for (const protocols::ProtocolDescription& d : protocols::ProtocolCatalog()) {
    if (d.name != order[0] && d.name != order[1]) order.push_back(d.name);
  }
  return order;
}

void Restart(Rig& rig) {
  rig.service.reset();
  rig.db.reset();
  storage::DatabaseOptions options;
  options.path = (rig.dir / "fesbench.db").string();
  auto reopened = storage::Database::Open(options);
  ASSERT_TRUE(reopened.ok()) << reopened.status().ToString();
  rig.db = std::move(reopened).value();
  rig.service = std::make_unique<RunService>(*rig.db, *rig.bench, rig.hub, rig.config);
  auto recovered = rig.service->RecoverAfterRestart();
  ASSERT_TRUE(recovered.ok()) << recovered.status().ToString();
  EXPECT_TRUE(recovered->failed_run_ids.empty());
}

TEST(RunOutcome, each_protocol_run_reads_back_the_same_after_a_restart) {
  RigOptions options;
  options.with_limits = false;  // the tolerance test records them
  Rig rig(options);
  std::map<std::int64_t, nlohmann::json> live;
  std::map<std::int64_t, std::string> protocol_of;
  for (const std::string& protocol : ProtocolsInRunOrder()) {
    auto started = rig.service->Start(rig.clinician, rig.session_id, protocol, {});
    ASSERT_TRUE(started.ok()) << protocol << ": " << started.status().ToString();
    auto view = rig.service->Wait(started->run_id, kWait);
    ASSERT_TRUE(view.ok()) << protocol;
    EXPECT_EQ(view->state, RunState::kDone) << protocol << ": " << view->reason;
    ASSERT_TRUE(view->outcome.has_value()) << protocol;
    EXPECT_TRUE(view->live);
    live[view->run_id] = api::RunViewToJson(*view);
    protocol_of[view->run_id] = protocol;
  }
  ASSERT_EQ(live.size(), protocols::ProtocolCatalog().size());

  // What each protocol concluded, typed.
  for (const auto& [run_id, json] : live) {
    const nlohmann::json& outcome = json.at("outcome");
    const std::string& protocol = protocol_of[run_id];
    if (protocol == "tolerance_test") {
      EXPECT_TRUE(outcome.at("session_revision").is_number_integer()) << outcome;
      EXPECT_TRUE(outcome.at("tolerance").at("subject_signalled_limit").is_boolean()) << outcome;
      EXPECT_EQ(json.at("result").at("session_revision"), outcome.at("session_revision"));
    }
    if (protocol == "rapid_parameterisation") {
      EXPECT_TRUE(outcome.at("parameter_set_id").is_number_integer()) << outcome;
      EXPECT_TRUE(outcome.contains("amplitude_search")) << outcome;
    }
    if (protocol == "daily_check") {
      EXPECT_TRUE(outcome.at("daily_check").at("verdict").is_string()) << outcome;
    }
    if (protocol == "tracking") {
      EXPECT_TRUE(outcome.contains("tracking")) << outcome;
    }
    if (protocol == "tracking" || protocol == "daily_check" ||
        protocol.rfind("prediction_", 0) == 0) {
      EXPECT_TRUE(outcome.at("used_parameter_set_id").is_number_integer())
          << protocol << ": " << outcome;
    }
  }

  Restart(rig);
  for (const auto& [run_id, before] : live) {
    auto stored = rig.service->Get(run_id);
    ASSERT_TRUE(stored.ok()) << stored.status().ToString();
    EXPECT_FALSE(stored->live);
    EXPECT_EQ(WithoutLiveOnly(api::RunViewToJson(*stored)), WithoutLiveOnly(before))
        << protocol_of[run_id];
    // The api reader reads what the server wrote.
    auto read = api::RunViewFromJson(api::RunViewToJson(*stored));
    ASSERT_TRUE(read.ok()) << read.status().ToString();
    EXPECT_EQ(api::RunViewToJson(*read).at("outcome"), before.at("outcome"));
  }
}

}  // namespace
}  // namespace fesbench::server::services::test
