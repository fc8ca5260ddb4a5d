// The run's wire forms (api/run.h): every writer's output reads back to the
// same value, readers name the field they cannot read, and not-finite
// numbers travel as null.

#include "api/run.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <limits>

#include "api/time_utc.h"

namespace fesbench::api {
namespace {

using nlohmann::json;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

TEST(RunWire, NamesRoundTrip) {
  for (StepPhase p : {StepPhase::kPrepare, StepPhase::kOffset, StepPhase::kStimulate,
                      StepPhase::kRest, StepPhase::kMove, StepPhase::kIdentify}) {
    EXPECT_EQ(ParseStepPhase(StepPhaseName(p)), p);
  }
  using Kind = SafetyEvent::Kind;
  for (Kind k : {Kind::kStimClamped, Kind::kSetpointClamped, Kind::kEStop, Kind::kEStopCleared,
                 Kind::kWatchdog}) {
    EXPECT_EQ(ParseSafetyEventKind(SafetyEventKindName(k)), k);
  }
  using EventKind = RunEvent::Kind;
  for (EventKind k : {EventKind::kState, EventKind::kProgress, EventKind::kSamples,
                      EventKind::kTrial, EventKind::kEnd, EventKind::kParameterSet}) {
    EXPECT_EQ(ParseRunEventKind(RunEventKindName(k)), k);
  }
  EXPECT_FALSE(ParseStepPhase("resting").has_value());
  EXPECT_FALSE(ParseRunEventKind("State").has_value());
}

TEST(RunWire, ProgressWithAnUnknownEtaTravelsAsNull) {
  Progress p{.fraction = 0.25,
             .eta_s = kNaN,
             .bench_elapsed_s = 10.0,
             .bench_total_s = 40.0,
             .step = 3,
             .phase = StepPhase::kStimulate};
  const json j = ProgressToJson(p);
  EXPECT_TRUE(j["eta_s"].is_null());
  EXPECT_EQ(j["phase"], "stimulate");
  const Result<Progress> back = ProgressFromJson(j);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->fraction, 0.25);
  EXPECT_TRUE(std::isnan(back->eta_s));
  EXPECT_EQ(back->bench_total_s, 40.0);
  EXPECT_EQ(back->step, 3u);
  EXPECT_EQ(back->phase, StepPhase::kStimulate);

  EXPECT_EQ(ProgressFromJson({{"fraction", "half"}}).status().field(), "fraction");
  EXPECT_EQ(ProgressFromJson({{"fraction", 0.5}, {"phase", "nap"}}).status().field(), "phase");
  EXPECT_EQ(ProgressFromJson(json::object()).status().field(), "fraction");
}

TEST(RunWire, RunViewReadsBackWhatItWrote) {
  RunView v;
  v.run_id = 12;
  v.session_id = 3;
  v.protocol = "tolerance_test";
  v.protocol_version = 2;
  v.parameters = {{"ramp_ma_per_s", 1.0}, {"ceiling_ma", 60.0}};
  v.state = RunState::kAborted;
  v.reason = "stopped by the clinician";
  v.owner = "clin";
  v.created_at = UtcTime(std::chrono::microseconds(1'795'000'000'123'456));
  v.finished_at = v.created_at + std::chrono::seconds(30);
  v.progress.fraction = 0.5;
  v.progress.eta_s = 12.0;
  v.progress.bench_elapsed_s = 30.0;
  v.progress.bench_total_s = 60.0;
  v.trial_ids = {41, 42};
  v.parameter_set_id = 9;
  v.safety_events = {{SafetyEvent::Kind::kStimClamped, 1.5, 70.0, 35.5, "session maximum"}};
  v.values = {{"max_tolerated_ma", 35.5}, {"undefined", kNaN}};
  v.result = {{"max_tolerated_ma", 35.5}};
  v.live = true;
  v.tolerance.emplace();
  v.tolerance->threshold_ma = 12.0;
  v.tolerance->max_tolerated_ma = 35.5;

  const json j = RunViewToJson(v);
  EXPECT_EQ(j["state"], "aborted");
  EXPECT_EQ(j["controller"], "clin");
  EXPECT_TRUE(j["started_at_utc"].is_null());
  EXPECT_TRUE(j["values"]["undefined"].is_null());
  EXPECT_EQ(j["tolerance"]["threshold_ma"], 12.0);

  const Result<RunView> back = RunViewFromJson(j);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->run_id, 12);
  EXPECT_EQ(back->session_id, 3);
  EXPECT_EQ(back->protocol_version, 2);
  EXPECT_EQ(back->parameters, v.parameters);
  EXPECT_EQ(back->state, RunState::kAborted);
  EXPECT_EQ(back->reason, v.reason);
  EXPECT_EQ(back->owner, "clin");
  EXPECT_EQ(back->created_at, v.created_at);
  EXPECT_FALSE(back->started_at.has_value());
  EXPECT_EQ(back->finished_at, v.finished_at);
  EXPECT_EQ(back->progress.fraction, 0.5);
  EXPECT_EQ(back->progress.eta_s, 12.0);
  EXPECT_EQ(back->progress.bench_total_s, 60.0);
  EXPECT_EQ(back->trial_ids, v.trial_ids);
  EXPECT_EQ(back->parameter_set_id, 9);
  ASSERT_EQ(back->safety_events.size(), 1u);
  EXPECT_EQ(back->safety_events[0].kind, SafetyEvent::Kind::kStimClamped);
  EXPECT_EQ(back->safety_events[0].applied, 35.5);
  EXPECT_EQ(back->values.at("max_tolerated_ma"), 35.5);
  EXPECT_TRUE(std::isnan(back->values.at("undefined")));
  EXPECT_EQ(back->result, v.result);
  EXPECT_TRUE(back->live);
}

TEST(RunWire, RunViewReadersNameWhatTheyCannotRead) {
  json j = RunViewToJson(RunView{});
  j["state"] = "paused";
  EXPECT_EQ(RunViewFromJson(j).status().field(), "state");
  j = RunViewToJson(RunView{});
  j["created_at_utc"] = "yesterday";
  EXPECT_EQ(RunViewFromJson(j).status().field(), "created_at_utc");
  j = RunViewToJson(RunView{});
  j.erase("run_id");
  EXPECT_EQ(RunViewFromJson(j).status().field(), "run_id");
  j = RunViewToJson(RunView{});
  j["added_by_a_newer_server"] = 1;
  EXPECT_TRUE(RunViewFromJson(j).ok());
}

TEST(RunWire, BenchStateRoundTrips) {
  BenchState s;
  s.kind = "sim";
  s.mode = "locked";
  s.busy = true;
  s.estopped = true;
  s.estop_source = "dds";
  s.owner = "clin";
  s.owner_user_id = 2;
  s.run_id = 7;
  s.protocol = "isometric_ramp_irc";
  s.run_state = RunState::kRunning;
  s.progress.fraction = 0.75;
  s.progress.phase = StepPhase::kRest;
  const Result<BenchState> back = BenchStateFromJson(BenchStateToJson(s));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->kind, "sim");
  EXPECT_EQ(back->mode, "locked");
  EXPECT_TRUE(back->busy);
  EXPECT_TRUE(back->estopped);
  EXPECT_EQ(back->estop_source, "dds");
  EXPECT_EQ(back->owner_user_id, 2);
  EXPECT_EQ(back->run_id, 7);
  EXPECT_EQ(back->run_state, RunState::kRunning);
  EXPECT_EQ(back->progress.fraction, 0.75);
  EXPECT_EQ(back->progress.phase, StepPhase::kRest);

  json bad = BenchStateToJson(s);
  bad["progress"]["phase"] = 4;
  EXPECT_EQ(BenchStateFromJson(bad).status().field(), "progress.phase");
}

TEST(RunWire, StreamEventsRoundTripByKind) {
  RunEvent samples;
  samples.kind = RunEvent::Kind::kSamples;
  samples.seq = 5;
  samples.run_id = 3;
  samples.first_sample = 80;
  samples.samples.trial = 1;
  samples.samples.trial_name = "free_swing_passive";
  samples.samples.t_s = {0.0, 0.005};
  samples.samples.angle_deg = {90.0, 89.5};
  samples.samples.target_deg = {90.0, 90.0};
  Result<RunEvent> a = RunEventFromJson(RunEventToJson(samples));
  ASSERT_TRUE(a.ok()) << a.status().ToString();
  EXPECT_EQ(a->kind, RunEvent::Kind::kSamples);
  EXPECT_EQ(a->seq, 5u);
  EXPECT_EQ(a->first_sample, 80u);
  EXPECT_EQ(a->samples.trial_name, "free_swing_passive");
  EXPECT_EQ(a->samples.angle_deg, samples.samples.angle_deg);
  EXPECT_EQ(a->samples.target_deg, samples.samples.target_deg);
  EXPECT_TRUE(a->samples.tau_scale_nm.empty());

  RunEvent end;
  end.kind = RunEvent::Kind::kEnd;
  end.run_id = 3;
  end.state = RunState::kDone;
  end.parameter_set_id = 4;
  end.result = {{"parameter_set_id", 4}};
  Result<RunEvent> b = RunEventFromJson(RunEventToJson(end));
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(b->state, RunState::kDone);
  EXPECT_EQ(b->parameter_set_id, 4);
  EXPECT_EQ(b->result, end.result);

  RunEvent trial;
  trial.kind = RunEvent::Kind::kTrial;
  trial.samples.trial = 2;
  trial.samples.trial_name = "rapid_passive";
  trial.trial_id = 17;
  Result<RunEvent> c = RunEventFromJson(RunEventToJson(trial));
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c->samples.trial, 2);
  EXPECT_EQ(c->samples.trial_name, "rapid_passive");
  EXPECT_EQ(c->trial_id, 17);

  EXPECT_EQ(RunEventFromJson({{"kind", "heartbeat"}}).status().field(), "kind");
  EXPECT_EQ(RunEventFromJson({{"kind", "end"}, {"state", "gone"}}).status().field(), "state");
}

}  // namespace
}  // namespace fesbench::api
