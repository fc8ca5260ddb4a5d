// The `isometric_step_irc` protocol (docs/PROTOCOLS.md, `isometric_step_irc`).

#include "server/protocols/catalog/parameters.h"
#include "server/protocols/protocol_registry.h"

namespace fesbench::server::protocols::catalog {
namespace {

// The knee locked at lock_angle_deg; one recorded stimulation envelope, the trial named after the
// protocol.
class IsometricStepIrc final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override { return {api::TrialKind::kStepIrc}; }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
};

ProtocolDescription IsometricStepIrc::Describe() const {
  return {
      .name = "isometric_step_irc",
      .version = 1,
      .title = "Isometric step IRC",
      .description =
          "Knee locked at 90°: 10 levels threshold→max, each a 3 s burst (0.5 s ramp, "
          "2.5 s hold) followed by 30 s rest; the mean of the last 0.5 s is the level's "
          "torque (§5.3.1, Appendix F part III).",
      .bench_mode = BenchMode::kLocked,
      .kind = ProtocolKind::kIsometric,
      .min_rest_s = 10.0,
      .parameters = {
          LockAngleDeg(), SettleS(1.5, "time to move to and lock the angle, s"), ThresholdMa(),
          MaxMa(),
          Count("levels", "number of amplitudes", {.value = 10.0, .min = 2.0, .max = 50.0}),
          Number("burst_s", "burst length incl. ramp, s", {.value = 3.0, .min = 0.5, .max = 20.0}),
          Number("ramp_s", "linear ramp at burst start, s",
                 {.value = 0.5, .min = 0.0, .max = 10.0}),
          Rest("rest_s", "relaxation after each burst, s",
               {.value = 30.0, .min = 10.0, .max = 300.0})}};
}

api::Status IsometricStepIrc::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  const ParameterValues& v = in.values;
  const double lock = v.at("lock_angle_deg");
  b.Prepare("lock", MotorMode::kLocked, lock, v.at("settle_s"));
  const model::SampledSignal envelope = model::MakeStimulus(
      "step_bursts", Pick(v, {"threshold_ma", "max_ma", "levels", "burst_s", "ramp_s", "rest_s"}));
  const int t = b.AddTrial(b.plan().protocol, MotorMode::kLocked);
  b.EnvelopeTrial(t, envelope, MotorMode::kLocked, lock, in.min_rest_s);
  return api::Status::Ok();
}

}  // namespace

std::unique_ptr<const Protocol> MakeIsometricStepIrc() {
  return std::make_unique<IsometricStepIrc>();
}

}  // namespace fesbench::server::protocols::catalog
