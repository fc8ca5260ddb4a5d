// The `isometric_prediction` protocol (docs/PROTOCOLS.md, `isometric_prediction`).

#include "server/protocols/catalog/parameters.h"
#include "server/protocols/protocol_registry.h"

namespace fesbench::server::protocols::catalog {
namespace {

// The knee locked at lock_angle_deg; one recorded stimulation envelope, the trial named after the
// protocol.
class IsometricPrediction final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override {
    return {api::TrialKind::kIsometricPrediction};
  }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
};

ProtocolDescription IsometricPrediction::Describe() const {
  return {
      .name = "isometric_prediction",
      .version = 1,
      .title = "Isometric torque prediction",
      .description =
          "Knee locked at 90°: the 11 s plateau profile of Fig. 5-8 (levels at threshold "
          "+ 5 mA and 25/50/75/100 % of the range), 200 Hz (§5.3.4, Appendix F part IV).",
      .bench_mode = BenchMode::kLocked,
      .kind = ProtocolKind::kIsometric,
      .min_rest_s = 0.0,
      .parameters = {LockAngleDeg(), SettleS(1.5, "time to move to and lock the angle, s"),
                     ThresholdMa(), MaxMa(),
                     Number("above_threshold_ma", "lowest plateau above threshold, mA",
                            {.value = 5.0, .min = 0.0, .max = 50.0}),
                     Number("lead_s", "zero stimulation before the first ramp, s",
                            {.value = 0.5, .min = 0.0, .max = 10.0}),
                     Number("ramp_s", "linear ramp between plateaus, s",
                            {.value = 0.25, .min = 0.005, .max = 5.0}),
                     Number("hold_s", "plateau hold, s", {.value = 0.75, .min = 0.0, .max = 10.0}),
                     Number("tail_s", "zero stimulation at the end, s",
                            {.value = 1.25, .min = 0.0, .max = 10.0})}};
}

api::Status IsometricPrediction::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  const ParameterValues& v = in.values;
  const double lock = v.at("lock_angle_deg");
  b.Prepare("lock", MotorMode::kLocked, lock, v.at("settle_s"));
  const model::SampledSignal envelope = model::MakeStimulus(
      "plateau_profile", Pick(v, {"threshold_ma", "max_ma", "above_threshold_ma", "lead_s",
                                  "ramp_s", "hold_s", "tail_s"}));
  const int t = b.AddTrial(b.plan().protocol, MotorMode::kLocked);
  b.EnvelopeTrial(t, envelope, MotorMode::kLocked, lock, in.min_rest_s);
  return api::Status::Ok();
}

}  // namespace

std::unique_ptr<const Protocol> MakeIsometricPrediction() {
  return std::make_unique<IsometricPrediction>();
}

}  // namespace fesbench::server::protocols::catalog
