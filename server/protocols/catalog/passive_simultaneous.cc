// The `passive_simultaneous` protocol (docs/PROTOCOLS.md, `passive_simultaneous`).

#include "server/protocols/catalog/parameters.h"
#include "server/protocols/protocol_registry.h"

namespace fesbench::server::protocols::catalog {
namespace {

// Sum-of-sines trajectories through the 90° reference (§5.4.2).
class PassiveSimultaneous final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override {
    return {api::TrialKind::kPassiveSimultaneous};
  }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
};

ProtocolDescription PassiveSimultaneous::Describe() const {
  return {.name = "passive_simultaneous",
          .version = 1,
          .title = "Simultaneous passive identification",
          .description =
              "Motor: two 10 s pseudo-random sum-of-six-sines trajectories scaled to the "
              "subject's range, set-points at 1 kHz, 200 Hz sampling; reference torque at 90° "
              "before each (§4.2.2, §5.4.2, Fig. 5-9).",
          .bench_mode = BenchMode::kMotor,
          .kind = ProtocolKind::kPassive,
          .min_rest_s = 0.0,
          .parameters = {Number("min_angle_deg", "lower angle of the trajectories, deg",
                                {.value = 30.0, .min = 10.0, .max = 110.0}, Scaling::kRangeMin),
                         Number("max_angle_deg", "upper angle of the trajectories, deg",
                                {.value = 100.0, .min = 10.0, .max = 110.0}, Scaling::kRangeMax),
                         Number("max_velocity_deg_s", "velocity limit, deg/s",
                                {.value = 200.0, .min = 10.0, .max = 400.0}),
                         WithLabel(Number("duration_s", "length of each trajectory, s",
                                          {.value = 10.0, .min = 2.5, .max = 60.0}),
                                   "Length of each trajectory"),
                         Count("trajectories", "number of trajectories",
                               {.value = 2.0, .min = 1.0, .max = 10.0}),
                         Count("seed", "seed of the first trajectory (then seed + 1, …)",
                               {.value = 1.0, .min = 0.0, .max = 4294967295.0}),
                         SettleS(2.0, "each move to the reference or start angle, s")}};
}

api::Status PassiveSimultaneous::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  const ParameterValues& v = in.values;
  if (v.at("min_angle_deg") > 90.0 || v.at("max_angle_deg") < 90.0) {
    // §5.4.2: the reference torque is measured at 90° of flexion.
    return api::Status::InvalidArgument(
        "min_angle_deg..max_angle_deg must include the 90° reference", "parameters");
  }
  const int n = static_cast<int>(v.at("trajectories"));
  for (int k = 0; k < n; ++k) {
    model::SumOfSinesOptions o;
    o.min_deg = v.at("min_angle_deg");
    o.max_deg = v.at("max_angle_deg");
    o.max_velocity_deg_s = v.at("max_velocity_deg_s");
    o.duration_s = v.at("duration_s");
    o.seed = static_cast<std::uint64_t>(v.at("seed")) + static_cast<std::uint64_t>(k);
    auto traj = std::make_shared<model::SumOfSinesTrajectory>(o);
    const int t =
        b.AddTrial("passive_simultaneous_" + std::to_string(k + 1), MotorMode::kPosition, true);
    b.Prepare("move to reference", MotorMode::kPosition, 90.0, v.at("settle_s"), true);
    b.Offset(t, MotorMode::kPosition, 90.0);
    b.MoveTo("move to start", traj->centre_deg(), v.at("settle_s"), t);
    b.Move("sum of sines", traj, t);
  }
  return api::Status::Ok();
}

}  // namespace

std::unique_ptr<const Protocol> MakePassiveSimultaneous() {
  return std::make_unique<PassiveSimultaneous>();
}

}  // namespace fesbench::server::protocols::catalog
