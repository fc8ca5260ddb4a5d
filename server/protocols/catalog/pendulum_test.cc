// The `pendulum_test` protocol (docs/PROTOCOLS.md, `pendulum_test`).

#include "server/protocols/catalog/parameters.h"
#include "server/protocols/protocol_registry.h"

namespace fesbench::server::protocols::catalog {
namespace {

// The pendulum test (MODEL.md, passive-only identification): each swing the motor takes the
// relaxed knee to the release angle and holds it, then lets go; the swing is recorded from the
// release, with no stimulation.
class PendulumTest final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override { return {api::TrialKind::kPendulum}; }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
};

ProtocolDescription PendulumTest::Describe() const {
  return {.name = "pendulum_test",
          .version = 1,
          .title = "Pendulum test",
          .description =
              "Motor, then free: the relaxed knee is taken to release_angle_deg, held "
              "release_hold_s and let go; it swings to rest without stimulation for "
              "release_swing_s; release_count times: the Wartenberg pendulum test, beyond the "
              "thesis (τ_pta and τ_ptv by method passive, Eq. 4.35 with J given or from the "
              "anthropometrics, §4.2.3).",
          .bench_mode = BenchMode::kMixed,
          .kind = ProtocolKind::kPassive,
          .min_rest_s = 0.0,
          .parameters = {
              Number("release_angle_deg", "knee angle the shank is let go at, deg",
                     {.value = 10.0, .min = 10.0, .max = 110.0}, Scaling::kRangeMin),
              Number("release_hold_s", "hold before each release, s",
                     {.value = 1.0, .min = 0.2, .max = 10.0}),
              Number("release_swing_s", "free swing recorded after each release, s",
                     {.value = 8.0, .min = 2.0, .max = 60.0}),
              Count("release_count", "number of releases", {.value = 2.0, .min = 1.0, .max = 10.0}),
              SettleS(2.0, "move to the release angle, s")}};
}

api::Status PendulumTest::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  const ParameterValues& v = in.values;
  const double angle = v.at("release_angle_deg");
  const auto releases = static_cast<int>(v.at("release_count"));
  for (int k = 1; k <= releases; ++k) {
    b.Prepare("move to the release angle", MotorMode::kPosition, angle, v.at("settle_s"), true);
    b.Rest("hold", v.at("release_hold_s"), 0.0, -1, MotorMode::kPosition, angle);
    const int t = b.AddTrial("pendulum_" + std::to_string(k), MotorMode::kDecoupled);
    b.Rest("free swing", v.at("release_swing_s"), 0.0, t, MotorMode::kDecoupled, angle);
  }
  return api::Status::Ok();
}

}  // namespace

std::unique_ptr<const Protocol> MakePendulumTest() { return std::make_unique<PendulumTest>(); }

}  // namespace fesbench::server::protocols::catalog
