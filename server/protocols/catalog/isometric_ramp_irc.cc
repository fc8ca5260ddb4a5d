// The `isometric_ramp_irc` protocol (docs/PROTOCOLS.md, `isometric_ramp_irc`).

#include "server/protocols/catalog/parameters.h"
#include "server/protocols/protocol_registry.h"

namespace fesbench::server::protocols::catalog {
namespace {

// The knee locked at lock_angle_deg; one recorded stimulation envelope, the trial named after the
// protocol.
class IsometricRampIrc final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override { return {api::TrialKind::kRampIrc}; }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
};

ProtocolDescription IsometricRampIrc::Describe() const {
  return {
      .name = "isometric_ramp_irc",
      .version = 1,
      .title = "Isometric ramp IRC",
      .description =
          "Knee locked at 90°: a 3 s conditioning burst at 75 % of the range, 2 impulses at "
          "max, 2 cosine ramps (2 s up, 2 s down) from threshold − 5 mA to max, 1 s rest "
          "between, 200 Hz (§5.3.3, Fig. 5-7, Appendix F part II).",
      .bench_mode = BenchMode::kLocked,
      .kind = ProtocolKind::kIsometric,
      .min_rest_s = 1.0,
      .parameters = {
          LockAngleDeg(), SettleS(1.5, "time to move to and lock the angle, s"), ThresholdMa(),
          MaxMa(),
          Number("conditioning_s", "conditioning burst length, s",
                 {.value = 3.0, .min = 0.0, .max = 10.0}),
          Number("conditioning_fraction", "conditioning level, fraction of threshold→max",
                 {.value = 0.75, .min = 0.0, .max = 1.0}),
          Count("impulses", "number of impulses at max", {.value = 2.0, .min = 0.0, .max = 20.0}),
          Count("ramps", "number of cosine ramps", {.value = 2.0, .min = 1.0, .max = 10.0}),
          Number("below_threshold_ma", "ramp start below threshold, mA",
                 {.value = 5.0, .min = 0.0, .max = 50.0}),
          Number("ramp_duration_s", "whole ramp (half up, half down), s",
                 {.value = 4.0, .min = 0.5, .max = 30.0}),
          Rest("rest_s", "zero stimulation after each element, s",
               {.value = 1.0, .min = 1.0, .max = 60.0})}};
}

api::Status IsometricRampIrc::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  const ParameterValues& v = in.values;
  const double lock = v.at("lock_angle_deg");
  b.Prepare("lock", MotorMode::kLocked, lock, v.at("settle_s"));
  const model::SampledSignal envelope = model::MakeStimulus(
      "isometric_ramp_irc",
      Pick(v, {"threshold_ma", "max_ma", "conditioning_s", "conditioning_fraction", "impulses",
               "ramps", "below_threshold_ma", "ramp_duration_s", "rest_s"}));
  const int t = b.AddTrial(b.plan().protocol, MotorMode::kLocked);
  b.EnvelopeTrial(t, envelope, MotorMode::kLocked, lock, in.min_rest_s);
  return api::Status::Ok();
}

}  // namespace

std::unique_ptr<const Protocol> MakeIsometricRampIrc() {
  return std::make_unique<IsometricRampIrc>();
}

}  // namespace fesbench::server::protocols::catalog
