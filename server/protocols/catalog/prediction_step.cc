// The `prediction_step` protocol (docs/PROTOCOLS.md, `prediction_step`).

#include "server/protocols/catalog/conclusions.h"
#include "server/protocols/catalog/parameters.h"
#include "server/protocols/protocol_registry.h"

namespace fesbench::server::protocols::catalog {
namespace {

// Decoupled at 90°; one recorded stimulation envelope, the trial named after the protocol.
class PredictionStep final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override { return {api::TrialKind::kPredictionStep}; }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
  // The set it is gated by (docs/SAFETY.md, model gate).
  api::RunOutcome Conclude(const RunConclusionInput& in, const RunResult& r) const override {
    return ConcludeWithLegSet(in, r);
  }
};

ProtocolDescription PredictionStep::Describe() const {
  return {.name = "prediction_step",
          .version = 1,
          .title = "Knee angle prediction: step",
          .description =
              "Decoupled: step at 75 % of the threshold→max range from 0.5 s for 3 s, then "
              "1.5 s without stimulation (§5.4.5, Fig. 5-12).",
          .bench_mode = BenchMode::kDecoupled,
          .kind = ProtocolKind::kPrediction,
          .min_rest_s = 0.0,
          .parameters = {ThresholdMa(), MaxMa(),
                         Number("level_fraction", "level as fraction of threshold→max",
                                {.value = 0.75, .min = 0.0, .max = 1.0}),
                         Number("onset_s", "zero stimulation before the step, s",
                                {.value = 0.5, .min = 0.0, .max = 10.0}),
                         Number("on_s", "step length, s", {.value = 3.0, .min = 0.1, .max = 30.0}),
                         Number("off_s", "zero stimulation after the step, s",
                                {.value = 1.5, .min = 0.0, .max = 30.0}),
                         SettleS(2.0, "swing after decoupling before recording, s")}};
}

api::Status PredictionStep::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  const ParameterValues& v = in.values;
  b.Prepare("decouple", MotorMode::kDecoupled, 90.0, v.at("settle_s"));
  const model::SampledSignal envelope = model::MakeStimulus(
      "prediction_step",
      Pick(v, {"threshold_ma", "max_ma", "level_fraction", "onset_s", "on_s", "off_s"}));
  const int t = b.AddTrial(b.plan().protocol, MotorMode::kDecoupled);
  b.EnvelopeTrial(t, envelope, MotorMode::kDecoupled, 90.0, 0.0);
  return api::Status::Ok();
}

}  // namespace

std::unique_ptr<const Protocol> MakePredictionStep() { return std::make_unique<PredictionStep>(); }

}  // namespace fesbench::server::protocols::catalog
