// A run's conclusion and its analysis belong to its protocol's class
// (docs/PROTOCOLS.md, "Adding a protocol"): ConcludeRun is the named
// protocol's Conclude, each family's figures come from its own class, and
// the engine runs the analysis a plan carries (Plan::analysis), none when
// the plan has none.

#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "api/run_outcome.h"
#include "model/simulate.h"
#include "server/protocols/protocol_registry.h"
#include "server/protocols/run_outcome.h"
#include "server/protocols/runner.h"
#include "tests/server/runner_rig.h"

namespace fesbench::server::protocols {
namespace {

using test::NoWatchdog;
using test::Rig;

// A result holding every family's figures, so that each protocol's
// outcome shows which of them its class concludes.
RunResult EveryFigure(RunState state) {
  RunResult r;
  r.state = state;
  r.values = {{"rb_amplitude_ma", 31.0},
              {"full_extension_amplitude_ma", 33.5},
              {"full_extension_reached", 1.0},
              {"e_rms_deg", 2.5}};
  return r;
}

RunConclusionInput Input(const std::string& protocol) {
  RunConclusionInput in;
  in.protocol = protocol;
  in.leg_parameter_set_id = 12;
  return in;
}

TEST(RunConclusion, ConcludeRunIsTheNamedProtocolsConclude) {
  for (const RegisteredProtocol& r : RegisteredProtocols()) {
    SCOPED_TRACE(r.description.name);
    for (RunState state : {RunState::kDone, RunState::kAborted, RunState::kRunning}) {
      const RunResult result = EveryFigure(state);
      const RunConclusionInput in = Input(r.description.name);
      EXPECT_EQ(api::RunOutcomeToJson(ConcludeRun(in, result)),
                api::RunOutcomeToJson(r.protocol->Conclude(in, result)));
    }
  }
}

TEST(RunConclusion, EachFamilyConcludesItsOwnFigures) {
  const RunResult done = EveryFigure(RunState::kDone);
  // The amplitude search is the rapid routine's alone.
  const api::RunOutcome rapid = ConcludeRun(Input("rapid_parameterisation"), done);
  ASSERT_TRUE(rapid.amplitude_search.has_value());
  EXPECT_EQ(rapid.amplitude_search->rb_amplitude_ma, 31.0);
  EXPECT_EQ(rapid.amplitude_search->full_extension_amplitude_ma, 33.5);
  EXPECT_EQ(rapid.amplitude_search->full_extension_reached, true);
  EXPECT_FALSE(rapid.used_parameter_set_id.has_value());
  // An isometric protocol concludes the common part only.
  const api::RunOutcome iso = ConcludeRun(Input("isometric_ramp_irc"), done);
  EXPECT_EQ(iso.state, RunState::kDone);
  EXPECT_FALSE(iso.amplitude_search || iso.tracking || iso.tolerance || iso.daily_check ||
               iso.used_parameter_set_id);
  // The prediction protocols and daily_check: the leg's set they are gated
  // by or compare with.
  for (const char* name : {"prediction_step", "prediction_ramp", "prediction_sine",
                           "prediction_random_binary", "daily_check"}) {
    SCOPED_TRACE(name);
    const api::RunOutcome o = ConcludeRun(Input(name), done);
    EXPECT_EQ(o.used_parameter_set_id, 12);
    EXPECT_FALSE(o.amplitude_search || o.tracking);
  }
  // Tracking: the set it names, else the leg's; its figures.
  RunConclusionInput named = Input("tracking");
  named.parameters["parameter_set_id"] = 5.0;
  const api::RunOutcome tracking = ConcludeRun(named, done);
  EXPECT_EQ(tracking.used_parameter_set_id, 5);
  ASSERT_TRUE(tracking.tracking.has_value());
  EXPECT_EQ(tracking.tracking->figures, done.values);
  EXPECT_EQ(ConcludeRun(Input("tracking"), done).used_parameter_set_id, 12);
  // The tolerance test: a ramp that reached its ceiling measured no max.
  RunResult ramp = done;
  ramp.tolerance = ToleranceResult{};
  ramp.tolerance->threshold_ma = 20.0;
  ramp.tolerance->max_tolerated_ma = 60.0;
  ramp.values["subject_signalled_limit"] = 0.0;
  RunConclusionInput tolerance = Input("tolerance_test");
  tolerance.parameters["ceiling_ma"] = 60.0;
  const api::RunOutcome ceiling = ConcludeRun(tolerance, ramp);
  ASSERT_TRUE(ceiling.tolerance.has_value());
  EXPECT_TRUE(ceiling.tolerance->ended_at_ceiling);
  EXPECT_EQ(ceiling.tolerance->message, CeilingMessage(tolerance.parameters));
  EXPECT_FALSE(ceiling.tolerance->max_tolerated_ma.has_value());
  EXPECT_FALSE(ceiling.amplitude_search.has_value());
  ramp.values["subject_signalled_limit"] = 1.0;
  const api::RunOutcome limit = ConcludeRun(tolerance, ramp);
  EXPECT_FALSE(limit.tolerance->ended_at_ceiling);
  EXPECT_EQ(limit.tolerance->max_tolerated_ma, 60.0);
}

TEST(RunConclusion, TheCommonPartFailsAnUnfinishedRunAndNamesNoProtocol) {
  const RunResult running = EveryFigure(RunState::kRunning);
  for (const char* name : {"rapid_parameterisation", "no_such_protocol"}) {
    SCOPED_TRACE(name);
    const api::RunOutcome o = ConcludeRun(Input(name), running);
    EXPECT_EQ(o.state, RunState::kFailed);
    EXPECT_EQ(o.reason, "the run ended in state running");
  }
  // A name no protocol has: the common part alone.
  const api::RunOutcome unknown =
      ConcludeRun(Input("no_such_protocol"), EveryFigure(RunState::kDone));
  EXPECT_EQ(api::RunOutcomeToJson(unknown),
            api::RunOutcomeToJson(ConcludeCommon(EveryFigure(RunState::kDone))));
  EXPECT_FALSE(unknown.amplitude_search.has_value());
}

// Counts its calls; fails the run with `failure` when it is not empty.
class CountingAnalysis final : public RunAnalysis {
 public:
  explicit CountingAnalysis(std::string failure) : failure_(std::move(failure)) {}
  StepPhase phase() const override { return StepPhase::kIdentify; }
  api::Status Analyse(const std::vector<RecordedTrial>& trials, const SubjectContext& /*subject*/,
                      const model::JointLimits& stops, RunResult& result) const override {
    ++calls;
    trials_seen = trials.size();
    stops_seen = stops;
    if (!failure_.empty()) return api::Status::FailedPrecondition(failure_);
    result.values["analysed"] = 1.0;
    return api::Status::Ok();
  }
  mutable int calls = 0;
  mutable std::size_t trials_seen = 0;
  mutable model::JointLimits stops_seen{};

 private:
  std::string failure_;
};

// The steps announced and the last progress of a run.
class Steps final : public RunObserver {
 public:
  void OnStep(std::size_t index, const Step& step) override {
    indices.push_back(index);
    phases.push_back(step.phase);
  }
  void OnProgress(const Progress& p) override { last = p; }
  std::vector<std::size_t> indices;
  std::vector<StepPhase> phases;
  Progress last;
};

TEST(RunAnalysisHook, APlanWithoutAnalysisRunsNone) {
  Rig rig(7);
  const SubjectContext ctx = test::WithKnownInertia(rig.subject);
  auto plan = MakePlan("isometric_impulse_irc", {}, ctx);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  EXPECT_EQ(plan->analysis, nullptr);
  Steps steps;
  const RunResult r = ProtocolRunner(rig.safe, &rig.log, &steps, NoWatchdog()).Run(*plan, ctx);
  ASSERT_EQ(r.state, RunState::kDone) << r.reason;
  ASSERT_EQ(steps.indices.size(), plan->steps.size());
  EXPECT_EQ(steps.indices.back(), plan->steps.size() - 1);
  EXPECT_EQ(steps.last.phase, StepPhase::kRest);
  EXPECT_FALSE(r.parameter_set.has_value());
  EXPECT_TRUE(r.parameter_set_trials.empty());
  EXPECT_FALSE(r.daily_check.has_value());
}

TEST(RunAnalysisHook, ThePlansAnalysisRunsOnceAfterTheLastStep) {
  Rig rig(7);
  const SubjectContext ctx = test::WithKnownInertia(rig.subject);
  auto plan = MakePlan("isometric_impulse_irc", {}, ctx);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  auto analysis = std::make_shared<CountingAnalysis>("");
  plan->analysis = analysis;
  Steps steps;
  const RunResult r = ProtocolRunner(rig.safe, &rig.log, &steps, NoWatchdog()).Run(*plan, ctx);
  ASSERT_EQ(r.state, RunState::kDone) << r.reason;
  EXPECT_EQ(analysis->calls, 1);
  EXPECT_EQ(analysis->trials_seen, plan->trials.size());
  EXPECT_EQ(analysis->stops_seen.min_angle_deg, rig.safe.bench_limits().min_angle_deg);
  EXPECT_EQ(analysis->stops_seen.max_angle_deg, rig.safe.bench_limits().max_angle_deg);
  EXPECT_EQ(r.values.at("analysed"), 1.0);
  // Announced as a step of its phase after the plan's, and the last progress's phase.
  ASSERT_EQ(steps.indices.size(), plan->steps.size() + 1);
  EXPECT_EQ(steps.indices.back(), plan->steps.size());
  EXPECT_EQ(steps.phases.back(), StepPhase::kIdentify);
  EXPECT_EQ(steps.last.phase, StepPhase::kIdentify);

  // A refusal fails the run with its message; the trials are kept.
  Rig again(7);
  auto failing = std::make_shared<CountingAnalysis>("the analysis refused");
  plan->analysis = failing;
  const RunResult f = ProtocolRunner(again.safe, &again.log, nullptr, NoWatchdog()).Run(*plan, ctx);
  EXPECT_EQ(f.state, RunState::kFailed);
  EXPECT_EQ(f.reason, "the analysis refused");
  EXPECT_EQ(failing->calls, 1);
  EXPECT_EQ(f.trials.size(), plan->trials.size());
}

}  // namespace
}  // namespace fesbench::server::protocols
