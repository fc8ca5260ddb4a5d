// The DDS front end (docs/API.md, "DDS") against real services on a temporary
// database, with a second participant as the client, on UDP loopback and a
// domain id unique to the test process (parallel ctest runs do not meet):
// a late joiner gets the latest parameter set of every leg and the bench
// state; e-stop over DDS stops a running protocol within one control period
// while bad and analyst tokens are refused with a reason (and audited as
// HTTP does); a real-time run's samples arrive complete and in order.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <thread>

#include "api/dds/fesbench.h"
#include "api/dds/participant.h"
#include "model/parameter_set.h"
#include "server/bench/virtual_subject.h"
#include "server/dds/dds_server.h"
#include "server/services/bench_service.h"
#include "server/services/commands.h"
#include "server/services/run_service.h"
#include "storage/audit_log.h"
#include "storage/parameter_sets.h"
#include "storage/sessions.h"
#include "storage/subjects.h"
#include "storage/trials.h"
#include "storage/users.h"
#include "tests/dds/dds_rig.h"

namespace fesbench::server::dds::testing {
namespace {

TEST(DdsServer, LateJoinerGetsTheLatestParameterSetOfEveryLegAndTheBenchState) {
  Rig rig(0.0);
  rig.StoreSet(rig.left_leg, 20.0);
  rig.StoreSet(rig.right_leg, 21.0);
  rig.StartServer();
  // A new version of the right leg's set while the server runs: published as
  // the event its storing raises (no polling of storage).
  const std::int64_t newest_right = rig.StoreSet(rig.right_leg, 27.5);
  const auto until = std::chrono::steady_clock::now() + kWait;
  while (rig.server->stats().parameter_sets < 3 && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(20ms);
  }
  ASSERT_EQ(rig.server->stats().parameter_sets, 3u);

  // Only now does the analyst join.
  auto client = rig.Client();
  ASSERT_TRUE(client);
  fdds::DataReader* sets = client->MakeReader(client->parameter_sets());
  fdds::DataReader* states = client->MakeReader(client->bench_state());
  std::map<std::int64_t, wire::ParameterSet> by_leg;
  std::vector<wire::BenchState> bench_states;
  while ((by_leg.size() < 2 || bench_states.empty()) && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(20ms);
    for (const auto& s : TakeAll<wire::ParameterSet>(sets)) by_leg[s.leg_id()] = s;
    for (const auto& s : TakeAll<wire::BenchState>(states)) bench_states.push_back(s);
  }
  ASSERT_EQ(by_leg.size(), 2u);
  EXPECT_EQ(by_leg[rig.left_leg].subject_id(), rig.subject_id);
  EXPECT_EQ(by_leg[rig.left_leg].version(), 1);
  EXPECT_EQ(by_leg[rig.right_leg].version(), 2);  // keep last per key: only the newest
  EXPECT_EQ(by_leg[rig.right_leg].parameter_set_id(), newest_right);
  const auto json = nlohmann::json::parse(by_leg[rig.right_leg].parameters_json());
  EXPECT_DOUBLE_EQ(json.at("contraction").at("pole_per_s").get<double>(), 27.5);
  EXPECT_EQ(by_leg[rig.right_leg].model(), "full");

  ASSERT_FALSE(bench_states.empty());
  const wire::BenchState& state = bench_states.back();
  EXPECT_EQ(state.bench_id(), "bench-under-test");
  EXPECT_EQ(state.kind(), rig.bench->kind());
  EXPECT_FALSE(state.estopped());
  EXPECT_FALSE(state.busy());
}

// Which set gates stimulation is on the topic: an approval is published as
// the set approved (an older version included), every sample names the
// leg's approved set, and a late joiner gets the approved set.
TEST(DdsServer, TheTopicSaysWhichSetOfALegIsApproved) {
  Rig rig(0.0);
  const std::int64_t first = rig.StoreSet(rig.right_leg, 20.0);
  rig.StartServer();
  rig.StoreSet(rig.right_leg, 27.5);
  const auto until = std::chrono::steady_clock::now() + kWait;
  const auto published = [&](std::uint64_t n) {
    while (rig.server->stats().parameter_sets < n && std::chrono::steady_clock::now() < until) {
      std::this_thread::sleep_for(20ms);
    }
    return rig.server->stats().parameter_sets;
  };
  ASSERT_EQ(published(2), 2u);  // the first at start, then the second
  storage::NewApproval approval;
  approval.parameter_set_id = first;
  approval.approved_by = "cora";
  approval.note = "fits the swing better";
  ASSERT_TRUE(storage::ParameterSetRepository(*rig.db).Approve(approval).ok());
  ASSERT_EQ(published(3), 3u);

  auto client = rig.Client();
  ASSERT_TRUE(client);
  fdds::DataReader* sets = client->MakeReader(client->parameter_sets());
  std::vector<wire::ParameterSet> got;
  while (got.empty() && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(20ms);
    for (const auto& s : TakeAll<wire::ParameterSet>(sets)) {
      if (s.leg_id() == rig.right_leg) got.push_back(s);
    }
  }
  ASSERT_EQ(got.size(), 1u);  // keep last per leg: the approval
  EXPECT_EQ(got[0].parameter_set_id(), first);
  EXPECT_TRUE(got[0].approved());
  EXPECT_EQ(got[0].approved_parameter_set_id(), first);

  // A newer version is published as a candidate that names the approved set.
  const std::int64_t third = rig.StoreSet(rig.right_leg, 30.0);
  got.clear();
  while (got.empty() && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(20ms);
    for (const auto& s : TakeAll<wire::ParameterSet>(sets)) got.push_back(s);
  }
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].parameter_set_id(), third);
  EXPECT_FALSE(got[0].approved());
  EXPECT_EQ(got[0].approved_parameter_set_id(), first);
}

TEST(DdsServer, EStopStopsARunningProtocolWithinOneControlPeriodAndBadTokensAreRefused) {
  Rig rig(1.0);
  rig.StartServer();
  auto client = rig.Client();
  ASSERT_TRUE(client);
  CommandClient commands(*client);

  services::SubscribeOptions watch_options;
  watch_options.capacity = 100000;
  auto watch = rig.hub.Subscribe(watch_options);
  auto run = rig.runs->Start(rig.clinician, rig.session_id, "isometric_ramp_irc", {});
  ASSERT_TRUE(run.ok()) << run.status().ToString();

  // A bad token: refused, nothing happens.
  wire::CommandReply bad = commands.Send(MakeCommand(wire::CMD_ESTOP, "fsb_not_a_token"));
  EXPECT_FALSE(bad.accepted());
  EXPECT_EQ(bad.code(), "unauthenticated");
  EXPECT_NE(bad.reason().find("token"), std::string::npos) << bad.reason();
  EXPECT_EQ(bad.bench_id(), "bench-under-test");
  EXPECT_FALSE(rig.runs->State().estopped);

  // An analyst may not start or cancel runs: refused with the reason.
  wire::Command start = MakeCommand(wire::CMD_START_RUN, rig.analyst_token);
  start.session_id(rig.session_id);
  start.protocol("tolerance_test");
  wire::CommandReply refused = commands.Send(start);
  EXPECT_FALSE(refused.accepted());
  EXPECT_EQ(refused.code(), "permission_denied");
  EXPECT_NE(refused.reason().find("role analyst may not"), std::string::npos) << refused.reason();
  wire::Command cancel = MakeCommand(wire::CMD_CANCEL_RUN, rig.analyst_token);
  cancel.run_id(run->run_id);
  EXPECT_EQ(commands.Send(cancel).code(), "permission_denied");
  EXPECT_TRUE(rig.runs->State().busy);

  // A command for another bench is not this server's to answer; e-stop by an
  // analyst (any signed-in user may press it, as over HTTP) is.
  // Wait until the bench is stimulating (the conditioning burst).
  bool stimulating = false;
  const auto until = std::chrono::steady_clock::now() + kWait;
  while (!stimulating && std::chrono::steady_clock::now() < until) {
    services::HubItemPtr item = watch->Next(100ms);
    if (!item || item->kind != services::HubItem::Kind::kSamples) continue;
    for (double u : item->samples.stim_ma) stimulating = stimulating || u > 1.0;
  }
  ASSERT_TRUE(stimulating);
  wire::Command estop = MakeCommand(wire::CMD_ESTOP, rig.analyst_token);
  estop.bench_id("bench-under-test");
  wire::CommandReply stopped = commands.Send(estop);
  EXPECT_TRUE(stopped.accepted()) << stopped.reason();
  EXPECT_EQ(stopped.code(), "ok");

  auto view = rig.runs->Wait(run->run_id, kWait);
  ASSERT_TRUE(view.ok());
  EXPECT_EQ(view->state, protocols::RunState::kAborted);
  EXPECT_EQ(view->reason, "e-stop");
  EXPECT_DOUBLE_EQ(rig.bench->ReadSensors().stim_ma, 0.0);
  const auto estop_event =
      std::find_if(view->safety_events.begin(), view->safety_events.end(),
                   [](const SafetyEvent& e) { return e.kind == SafetyEvent::Kind::kEStop; });
  ASSERT_NE(estop_event, view->safety_events.end());
  // The protocol stopped within one control period (1 ms) of the e-stop:
  // recording ends at the next 200 Hz sample at the latest, and any sample
  // later than one control period after it has stimulation zero; before it
  // the bench was stimulating.
  std::size_t after = 0;
  double last_t_s = 0.0, max_stim_ma = 0.0;
  for (std::int64_t id : view->trial_ids) {
    auto trial = storage::TrialRepository(*rig.db).Get(id);
    ASSERT_TRUE(trial.ok());
    const std::vector<double>* t_ptr = trial->Values("t_s");
    const std::vector<double>* stim_ptr = trial->Values("stim_ma");
    ASSERT_TRUE(t_ptr && stim_ptr);
    const auto& t = *t_ptr;
    const auto& stim = *stim_ptr;
    for (std::size_t i = 0; i < t.size(); ++i) {
      last_t_s = std::max(last_t_s, t[i]);
      max_stim_ma = std::max(max_stim_ma, stim[i]);
      if (t[i] > estop_event->t_s + 1e-3) {
        ++after;
        EXPECT_EQ(stim[i], 0.0) << "t " << t[i];
      }
    }
  }
  EXPECT_TRUE(rig.runs->State().estopped);
  EXPECT_EQ(rig.runs->State().estop_source, "dds (ana)");

  // The audit log has the e-stop and the refusals, as HTTP writes them.
  auto entries = storage::AuditLog(*rig.db).List({});
  ASSERT_TRUE(entries.ok());
  int estops = 0, refusals = 0;
  for (const auto& e : *entries) {
    if (e.entry.action == "bench.estop" && e.entry.actor == "ana") ++estops;
    if ((e.entry.action == "dds start_run" || e.entry.action == "dds cancel_run") &&
        e.entry.outcome == "permission_denied" && e.entry.actor == "ana") {
      ++refusals;
    }
  }
  EXPECT_EQ(estops, 1);
  EXPECT_EQ(refusals, 2);
  EXPECT_LE(after, 1u);
  EXPECT_LE(last_t_s, estop_event->t_s + 1e-3 + 1.0 / 200.0);
  EXPECT_GT(max_stim_ma, 1.0);
}

// Failed tokens in DDS commands are audited (never the token), a flood
// only up to a burst plus one row per second that counts the rest, and a
// valid e-stop right after the flood still latches.
TEST(DdsCommands, FailedSignInsAreAuditedWithoutFloodingTheLog) {
  Rig rig(0.0);
  const int kFlood = 40;
  for (int i = 0; i < kFlood; ++i) {
    EXPECT_EQ(rig.commands->EStop("fsb_not_a_token_" + std::to_string(i)).code(),
              api::ErrorCode::kUnauthenticated);
  }
  EXPECT_EQ(rig.commands->CancelRun("", 7).code(), api::ErrorCode::kUnauthenticated);
  const auto failed_rows = [&rig] {
    std::vector<storage::AuditEntry> rows;
    auto all = storage::AuditLog(*rig.db).List({});
    EXPECT_TRUE(all.ok());
    for (const auto& e : *all) {
      if (e.entry.outcome == "unauthenticated") rows.push_back(e);
    }
    return rows;
  };
  auto rows = failed_rows();
  const int burst = static_cast<int>(services::CommandService::kFailedSignInBurst);
  ASSERT_GE(static_cast<int>(rows.size()), burst);
  ASSERT_LE(static_cast<int>(rows.size()), burst + 1);  // a refill if the loop took > 1 s
  for (const auto& e : rows) {
    EXPECT_EQ(e.entry.actor, "dds client");
    EXPECT_EQ(e.entry.action, "dds estop");
    EXPECT_EQ(e.entry.target, "bench");
    EXPECT_EQ(e.entry.request_summary.find("fsb_"), std::string::npos);
    EXPECT_FALSE(e.entry.user_id.has_value());
  }
  std::this_thread::sleep_for(1100ms);
  EXPECT_EQ(rig.commands->Heartbeat("fsb_still_wrong", 9).code(), api::ErrorCode::kUnauthenticated);
  rows = failed_rows();
  const auto& last = rows.front();  // newest first
  EXPECT_EQ(last.entry.action, "dds heartbeat");
  EXPECT_EQ(last.entry.target, "runs/9");
  EXPECT_NE(last.entry.request_summary.find("more failed since the last row"), std::string::npos)
      << last.entry.request_summary;

  EXPECT_TRUE(rig.commands->EStop(rig.analyst_token).ok());
  EXPECT_TRUE(rig.runs->State().estopped);
}

TEST(DdsServer, RealTimeRunSamplesArriveCompleteAndInOrderAt200Hz) {
  Rig rig(1.0);
  rig.StartServer();
  auto client = rig.Client();
  ASSERT_TRUE(client);
  fdds::DataReader* samples = client->MakeReader(client->samples());
  fdds::DataReader* events = client->MakeReader(client->run_events());
  CommandClient commands(*client);
  ASSERT_TRUE(WaitMatched(samples));
  ASSERT_TRUE(WaitMatched(events));

  // The run is started over DDS by the clinician: the same RunService call as HTTP.
  wire::Command start = MakeCommand(wire::CMD_START_RUN, rig.clinician_token);
  start.session_id(rig.session_id);
  start.protocol("tolerance_test");
  for (const auto& [name, value] : kShortTolerance) {
    wire::Parameter p;
    p.name(name);
    p.value(value);
    start.parameters().push_back(p);
  }
  wire::CommandReply reply = commands.Send(start);
  ASSERT_TRUE(reply.accepted()) << reply.code() << ": " << reply.reason();
  const std::int64_t run_id = reply.run_id();
  ASSERT_GT(run_id, 0);
  wire::Command heartbeat = MakeCommand(wire::CMD_HEARTBEAT, rig.clinician_token);
  heartbeat.run_id(run_id);
  EXPECT_TRUE(commands.Send(heartbeat).accepted());

  std::vector<wire::SampleBlock> blocks;
  bool ended = false;
  std::vector<wire::RunState> states;
  const auto until = std::chrono::steady_clock::now() + kWait;
  while (!ended && std::chrono::steady_clock::now() < until) {
    samples->wait_for_unread_message(eprosima::fastrtps::Duration_t(0, 20000000));
    for (auto& b : TakeAll<wire::SampleBlock>(samples)) {
      if (b.run_id() == run_id) blocks.push_back(b);
    }
    for (const auto& e : TakeAll<wire::RunEvent>(events)) {
      if (e.run_id() != run_id) continue;
      states.push_back(e.state());
      if (e.end()) ended = true;
    }
  }
  ASSERT_TRUE(ended);
  // Blocks sent before the end event may still be in flight.
  std::this_thread::sleep_for(100ms);
  for (auto& b : TakeAll<wire::SampleBlock>(samples)) {
    if (b.run_id() == run_id) blocks.push_back(b);
  }
  ASSERT_FALSE(states.empty());
  EXPECT_NE(std::find(states.begin(), states.end(), wire::RUN_RUNNING), states.end());
  EXPECT_EQ(states.back(), wire::RUN_DONE);

  auto view = rig.runs->Wait(run_id, kWait);
  ASSERT_TRUE(view.ok());
  ASSERT_EQ(view->state, protocols::RunState::kDone) << view->reason;
  std::size_t stored = 0;
  for (std::int64_t id : view->trial_ids)
    stored += storage::TrialRepository(*rig.db).Get(id)->num_samples();

  ASSERT_FALSE(blocks.empty());
  std::uint64_t next_sample = 0;
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    const wire::SampleBlock& b = blocks[i];
    EXPECT_EQ(b.block_seq(), i + 1);           // none lost, none reordered
    EXPECT_EQ(b.first_sample(), next_sample);  // contiguous
    ASSERT_EQ(b.channels().size(), 4u);
    for (const auto& c : b.channels()) EXPECT_EQ(c.values().size(), b.t_s().size()) << c.name();
    for (std::size_t k = 1; k < b.t_s().size(); ++k) {
      EXPECT_NEAR(b.t_s()[k] - b.t_s()[k - 1], 1.0 / 200.0, 1e-9);  // 200 Hz
    }
    next_sample += b.t_s().size();
  }
  EXPECT_EQ(next_sample, stored);
  EXPECT_EQ(blocks.front().channels()[0].name(), "stim");
  EXPECT_EQ(blocks.front().channels()[2].unit(), "N.m");
}

}  // namespace
}  // namespace fesbench::server::dds::testing
