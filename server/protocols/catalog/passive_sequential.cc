// The `passive_sequential` protocol (docs/PROTOCOLS.md, `passive_sequential`).

#include <algorithm>

#include "server/protocols/catalog/parameters.h"
#include "server/protocols/protocol_registry.h"

namespace fesbench::server::protocols::catalog {
namespace {

// Positions then velocities, each its own motor trial (§5.4.1).
class PassiveSequential final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override {
    return {api::TrialKind::kPassivePositions, api::TrialKind::kPassiveVelocities};
  }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
};

ProtocolDescription PassiveSequential::Describe() const {
  return {.name = "passive_sequential",
          .version = 1,
          .title = "Sequential passive identification",
          .description =
              "Motor: 20 positions from max_angle_deg to full extension and back, each held "
              "10 s (50-sample means); then 8 speeds × 2 directions of 2 s moves with 10 s "
              "pauses, the last 1 s used (§5.4.1).",
          .bench_mode = BenchMode::kMotor,
          .kind = ProtocolKind::kPassive,
          .min_rest_s = 2.0,
          .parameters = {
              Number("min_angle_deg", "full extension for the subject, deg",
                     {.value = 30.0, .min = 10.0, .max = 110.0}, Scaling::kRangeMin),
              Number("max_angle_deg", "first (largest flexion) angle, deg",
                     {.value = 110.0, .min = 10.0, .max = 110.0}, Scaling::kRangeMax),
              Number("reference_deg", "reference angle (offset torque), deg",
                     {.value = 90.0, .min = 10.0, .max = 110.0}),
              Count("positions", "angles per pass", {.value = 20.0, .min = 2.0, .max = 100.0}),
              Number("hold_s", "hold at each angle, s", {.value = 10.0, .min = 0.5, .max = 120.0}),
              Number("move_s", "move between angles, s", {.value = 1.0, .min = 0.1, .max = 10.0}),
              Count("speeds", "number of speeds", {.value = 8.0, .min = 1.0, .max = 30.0}),
              Number("max_speed_deg_s", "fastest speed, deg/s",
                     {.value = 30.0, .min = 1.0, .max = 200.0}),
              Rest("pause_s", "pause before each constant-velocity move, s",
                   {.value = 10.0, .min = 2.0, .max = 120.0}),
              SettleS(2.0, "move to the reference angle before each part, s")}};
}

api::Status PassiveSequential::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  const ParameterValues& v = in.values;
  const double ref = v.at("reference_deg");
  auto positions = std::make_shared<model::PiecewisePolynomialTrajectory>(
      model::PassivePositions({ref, v.at("max_angle_deg"), v.at("min_angle_deg"),
                               static_cast<int>(v.at("positions")), v.at("hold_s"), v.at("move_s"),
                               10.0})
          .trajectory);
  model::PassiveVelocitiesOptions pv;
  pv.reference_deg = ref;
  pv.min_deg = v.at("min_angle_deg");
  pv.speeds = static_cast<int>(v.at("speeds"));
  pv.max_speed_deg_s = v.at("max_speed_deg_s");
  pv.pause_s = std::max(v.at("pause_s"), in.min_rest_s);
  auto velocities = std::make_shared<model::PiecewisePolynomialTrajectory>(
      model::PassiveVelocities(pv).trajectory);
  const int tp = b.AddTrial("passive_positions", MotorMode::kPosition, true);
  b.Prepare("move to reference", MotorMode::kPosition, ref, v.at("settle_s"), true);
  b.Offset(tp, MotorMode::kPosition, ref);
  b.Move("positions", positions, tp);
  const int tv = b.AddTrial("passive_velocities", MotorMode::kPosition, true);
  b.Prepare("move to reference", MotorMode::kPosition, ref, v.at("settle_s"), true);
  b.Offset(tv, MotorMode::kPosition, ref);
  b.Move("velocities", velocities, tv);
  return api::Status::Ok();
}

}  // namespace

std::unique_ptr<const Protocol> MakePassiveSequential() {
  return std::make_unique<PassiveSequential>();
}

}  // namespace fesbench::server::protocols::catalog
