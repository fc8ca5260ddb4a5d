// The `isometric_impulse_irc` protocol (docs/PROTOCOLS.md, `isometric_impulse_irc`).

#include "server/protocols/catalog/parameters.h"
#include "server/protocols/protocol_registry.h"

namespace fesbench::server::protocols::catalog {
namespace {

// The knee locked at lock_angle_deg; one recorded stimulation envelope, the trial named after the
// protocol.
class IsometricImpulseIrc final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override { return {api::TrialKind::kImpulseIrc}; }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
};

ProtocolDescription IsometricImpulseIrc::Describe() const {
  return {
      .name = "isometric_impulse_irc",
      .version = 1,
      .title = "Isometric impulse IRC",
      .description =
          "Knee locked at 90°: 30 single pulses from below threshold to max, 1 s apart; "
          "the peak torque after each is the level's response (§5.3.2).",
      .bench_mode = BenchMode::kLocked,
      .kind = ProtocolKind::kIsometric,
      .min_rest_s = 0.5,
      .parameters = {
          LockAngleDeg(), SettleS(1.5, "time to move to and lock the angle, s"), ThresholdMa(),
          MaxMa(), Count("count", "number of pulses", {.value = 30.0, .min = 2.0, .max = 200.0}),
          Number("below_threshold_ma", "first pulse below threshold, mA",
                 {.value = 5.0, .min = 0.0, .max = 50.0}),
          Rest("interval_s", "time between pulses, s", {.value = 1.0, .min = 0.5, .max = 10.0})}};
}

api::Status IsometricImpulseIrc::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  const ParameterValues& v = in.values;
  const double lock = v.at("lock_angle_deg");
  b.Prepare("lock", MotorMode::kLocked, lock, v.at("settle_s"));
  const model::SampledSignal envelope = model::MakeStimulus(
      "impulse_series",
      Pick(v, {"threshold_ma", "max_ma", "count", "below_threshold_ma", "interval_s"}));
  const int t = b.AddTrial(b.plan().protocol, MotorMode::kLocked);
  b.EnvelopeTrial(t, envelope, MotorMode::kLocked, lock, in.min_rest_s);
  return api::Status::Ok();
}

}  // namespace

std::unique_ptr<const Protocol> MakeIsometricImpulseIrc() {
  return std::make_unique<IsometricImpulseIrc>();
}

}  // namespace fesbench::server::protocols::catalog
