// fesbench-dds-monitor's functions against a real DdsServer (tests/dds/dds_rig.h):
// list benches, show the latest parameter set, e-stop (refused for a bad
// token), record a live run's samples as CSV, and a clear error when no
// server answers within the timeout.
#include "clients/dds_monitor/monitor.h"

#include <gtest/gtest.h>

#include <sstream>
#include <string>

#include "tests/dds/dds_rig.h"

namespace fesbench::server::dds::testing {
namespace {

dds_monitor::MonitorOptions MonitorOn(int domain, double timeout_s = 10.0) {
  dds_monitor::MonitorOptions o;
  o.participant.domain_id = domain;
  o.participant.transport = wire::Transport::kUdpLoopback;
  o.timeout_s = timeout_s;
  return o;
}

TEST(DdsMonitor, ListsBenchesShowsParameterSetsAndEStops) {
  Rig rig(0.0);
  const std::int64_t set_id = rig.StoreSet(rig.left_leg, 23.0);
  rig.StartServer();
  const auto options = MonitorOn(rig.domain);

  std::ostringstream benches;
  auto n = dds_monitor::ListBenches(options, benches);
  ASSERT_TRUE(n.ok()) << n.status().ToString();
  EXPECT_EQ(*n, 1);
  EXPECT_NE(benches.str().find("bench-under-test  kind sim  mode idle  no e-stop  idle"),
            std::string::npos)
      << benches.str();

  std::ostringstream set;
  ASSERT_TRUE(dds_monitor::ShowParameterSet(options, rig.subject_id, rig.left_leg, set).ok());
  EXPECT_NE(set.str().find("parameter set " + std::to_string(set_id) + " version 1"),
            std::string::npos)
      << set.str();
  EXPECT_NE(set.str().find("\"pole_per_s\": 23.0"), std::string::npos) << set.str();
  std::ostringstream none;
  EXPECT_EQ(dds_monitor::ShowParameterSet(options, rig.subject_id, rig.right_leg, none).code(),
            api::ErrorCode::kNotFound);

  std::ostringstream refused;
  const api::Status bad = dds_monitor::SendEStop(options, "fsb_wrong", "", refused);
  EXPECT_EQ(bad.code(), api::ErrorCode::kUnauthenticated);
  EXPECT_NE(refused.str().find("refused: unauthenticated"), std::string::npos) << refused.str();
  EXPECT_FALSE(rig.runs->State().estopped);

  std::ostringstream latched;
  ASSERT_TRUE(dds_monitor::SendEStop(options, rig.analyst_token, "bench-under-test", latched).ok());
  EXPECT_EQ(latched.str(), "bench-under-test: e-stop latched\n");
  EXPECT_TRUE(rig.runs->State().estopped);
}

TEST(DdsMonitor, RecordsALiveRunsSamplesAsCsv) {
  Rig rig(1.0);
  rig.StartServer();
  auto run = rig.runs->Start(rig.clinician, rig.session_id, "isometric_ramp_irc", {});
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  std::ostringstream csv;
  auto n = dds_monitor::StreamSamples(MonitorOn(rig.domain), run->run_id, true, 120, csv);
  ASSERT_TRUE(n.ok()) << n.status().ToString();
  EXPECT_EQ(*n, 120u);
  ASSERT_TRUE(rig.runs->Cancel(rig.clinician, run->run_id).ok());

  std::istringstream lines(csv.str());
  std::string line;
  std::getline(lines, line);
  EXPECT_EQ(line, "run_id,trial,t_s,stim_mA,angle_deg,torque_N.m,accel_m/s2");
  int rows = 0;
  double last_t = -1.0;
  while (std::getline(lines, line)) {
    ++rows;
    std::istringstream fields(line);
    std::string run_field, trial_field, t_field;
    std::getline(fields, run_field, ',');
    std::getline(fields, trial_field, ',');
    std::getline(fields, t_field, ',');
    EXPECT_EQ(std::stoll(run_field), run->run_id);
    const double t = std::stod(t_field);
    if (last_t >= 0.0) {
      EXPECT_NEAR(t - last_t, 1.0 / 200.0, 1e-9);  // in order, none missing
    }
    last_t = t;
  }
  EXPECT_EQ(rows, 120);
}

TEST(DdsMonitor, SaysClearlyWhenNoServerAnswers) {
  const int lonely_domain = UniqueDomain();
  std::ostringstream out;
  auto n = dds_monitor::ListBenches(MonitorOn(lonely_domain, 0.5), out);
  ASSERT_FALSE(n.ok());
  EXPECT_EQ(n.status().code(), api::ErrorCode::kUnavailable);
  EXPECT_NE(n.status().message().find("no fesbench server found on DDS domain " +
                                      std::to_string(lonely_domain)),
            std::string::npos)
      << n.status().message();
  EXPECT_EQ(dds_monitor::SendEStop(MonitorOn(lonely_domain, 0.5), "t", "", out).code(),
            api::ErrorCode::kUnavailable);
}

}  // namespace
}  // namespace fesbench::server::dds::testing
