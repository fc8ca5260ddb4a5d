// The `pendulum_test` protocol (docs/PROTOCOLS.md, `pendulum_test`): the
// relaxed knee taken to the release angle, held, let go and recorded
// swinging, release_count times, with no stimulation.
#include <gtest/gtest.h>

#include <algorithm>

#include "api/trial_kind.h"
#include "server/protocols/plan.h"
#include "server/protocols/protocol_registry.h"

namespace fesbench::server::protocols {
namespace {

SubjectContext Leg() {
  SubjectContext s;
  s.threshold_ma = 22.0;
  s.max_tolerated_ma = 42.0;
  s.min_angle_deg = 25.0;
  s.max_angle_deg = 105.0;
  return s;
}

TEST(PendulumTest, IsRegisteredAfterTheFreeSwingAndRecordsPendulumTrials) {
  const RegisteredProtocol* p = FindRegisteredProtocol("pendulum_test");
  ASSERT_NE(p, nullptr);
  EXPECT_EQ(p->records, std::vector<api::TrialKind>{api::TrialKind::kPendulum});
  EXPECT_EQ(RecordingProtocol(api::TrialKind::kPendulum), "pendulum_test");
  EXPECT_EQ(p->description.kind, ProtocolKind::kPassive);
  EXPECT_EQ(p->description.bench_mode, BenchMode::kMixed);
  EXPECT_FALSE(Stimulates(p->description));
  // Listed after free_swing_passive, as docs/PROTOCOLS.md orders it.
  const auto& catalog = ProtocolCatalog();
  const auto at = [&](std::string_view name) {
    return std::find_if(catalog.begin(), catalog.end(),
                        [&](const ProtocolDescription& d) { return d.name == name; }) -
           catalog.begin();
  };
  EXPECT_EQ(at("pendulum_test"), at("free_swing_passive") + 1);
}

TEST(PendulumTest, EachReleaseIsAMoveAHoldAndARecordedFreeSwingWithoutStimulation) {
  api::Result<Plan> plan = MakePlan("pendulum_test", {{"release_count", 3.0}}, Leg());
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  ASSERT_EQ(plan->trials.size(), 3u);
  for (std::size_t k = 0; k < plan->trials.size(); ++k) {
    EXPECT_EQ(plan->trials[k].name, "pendulum_" + std::to_string(k + 1));
    EXPECT_EQ(plan->trials[k].mode, MotorMode::kDecoupled);
    EXPECT_EQ(api::TrialKindOf(plan->trials[k].name), api::TrialKind::kPendulum);
  }
  // The release angle defaults to the leg's extended end of its range.
  EXPECT_DOUBLE_EQ(plan->parameters.at("release_angle_deg"), 25.0);
  ASSERT_EQ(plan->steps.size(), 9u);
  for (std::size_t i = 0; i < plan->steps.size(); i += 3) {
    const Step& move = plan->steps[i];
    const Step& hold = plan->steps[i + 1];
    const Step& swing = plan->steps[i + 2];
    EXPECT_EQ(move.phase, StepPhase::kPrepare);
    EXPECT_EQ(move.motor_mode, MotorMode::kPosition);
    EXPECT_TRUE(move.move_from_current);
    EXPECT_DOUBLE_EQ(move.setpoint_deg, 25.0);
    EXPECT_EQ(move.ticks, 2000);
    EXPECT_EQ(hold.motor_mode, MotorMode::kPosition);
    EXPECT_EQ(hold.trial, -1);
    EXPECT_EQ(hold.ticks, 1000);
    EXPECT_EQ(swing.motor_mode, MotorMode::kDecoupled);
    EXPECT_EQ(swing.trial, static_cast<int>(i / 3));
    EXPECT_EQ(swing.ticks, 8000);
  }
  for (const Step& s : plan->steps) {
    EXPECT_EQ(s.envelope, nullptr);
    EXPECT_FALSE(s.tolerance_ramp);
    EXPECT_FALSE(s.closed_loop);
  }
  EXPECT_EQ(plan->total_ticks(), 3 * 11000);
}

}  // namespace
}  // namespace fesbench::server::protocols
