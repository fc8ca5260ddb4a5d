// The `prediction_sine` protocol (docs/PROTOCOLS.md, `prediction_sine`).

#include "server/protocols/catalog/conclusions.h"
#include "server/protocols/catalog/parameters.h"
#include "server/protocols/protocol_registry.h"

namespace fesbench::server::protocols::catalog {
namespace {

// Decoupled at 90°; one recorded stimulation envelope, the trial named after the protocol.
class PredictionSine final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override { return {api::TrialKind::kPredictionSine}; }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
  // The set it is gated by (docs/SAFETY.md, model gate).
  api::RunOutcome Conclude(const RunConclusionInput& in, const RunResult& r) const override {
    return ConcludeWithLegSet(in, r);
  }
};

ProtocolDescription PredictionSine::Describe() const {
  return {.name = "prediction_sine",
          .version = 1,
          .title = "Knee angle prediction: swept sine",
          .description =
              "Decoupled: cosine cycles of period 5, 2 and 1 s between threshold + 5 mA and "
              "max, then 1 s without stimulation (§5.4.5).",
          .bench_mode = BenchMode::kDecoupled,
          .kind = ProtocolKind::kPrediction,
          .min_rest_s = 0.0,
          .parameters = {ThresholdMa(), MaxMa(),
                         Number("above_threshold_ma", "lower level above threshold, mA",
                                {.value = 5.0, .min = 0.0, .max = 50.0}),
                         Number("tail_s", "zero stimulation at the end, s",
                                {.value = 1.0, .min = 0.0, .max = 10.0}),
                         SettleS(2.0, "swing after decoupling before recording, s")}};
}

api::Status PredictionSine::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  const ParameterValues& v = in.values;
  b.Prepare("decouple", MotorMode::kDecoupled, 90.0, v.at("settle_s"));
  const model::SampledSignal envelope = model::MakeStimulus(
      "prediction_sine", Pick(v, {"threshold_ma", "max_ma", "above_threshold_ma", "tail_s"}));
  const int t = b.AddTrial(b.plan().protocol, MotorMode::kDecoupled);
  b.EnvelopeTrial(t, envelope, MotorMode::kDecoupled, 90.0, 0.0);
  return api::Status::Ok();
}

}  // namespace

std::unique_ptr<const Protocol> MakePredictionSine() { return std::make_unique<PredictionSine>(); }

}  // namespace fesbench::server::protocols::catalog
