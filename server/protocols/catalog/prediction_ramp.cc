// The `prediction_ramp` protocol (docs/PROTOCOLS.md, `prediction_ramp`).

#include "server/protocols/catalog/conclusions.h"
#include "server/protocols/catalog/parameters.h"
#include "server/protocols/protocol_registry.h"

namespace fesbench::server::protocols::catalog {
namespace {

// Decoupled at 90°; one recorded stimulation envelope, the trial named after the protocol.
class PredictionRamp final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override { return {api::TrialKind::kPredictionRamp}; }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
  // The set it is gated by (docs/SAFETY.md, model gate).
  api::RunOutcome Conclude(const RunConclusionInput& in, const RunResult& r) const override {
    return ConcludeWithLegSet(in, r);
  }
};

ProtocolDescription PredictionRamp::Describe() const {
  return {.name = "prediction_ramp",
          .version = 1,
          .title = "Knee angle prediction: ramp",
          .description = "Decoupled: amplitude 0→max in 5 s and back to 0 in 5 s (§5.4.5).",
          .bench_mode = BenchMode::kDecoupled,
          .kind = ProtocolKind::kPrediction,
          .min_rest_s = 0.0,
          .parameters = {
              MaxMa(), Number("up_s", "ramp-up time, s", {.value = 5.0, .min = 0.1, .max = 60.0}),
              Number("down_s", "ramp-down time, s", {.value = 5.0, .min = 0.1, .max = 60.0}),
              SettleS(2.0, "swing after decoupling before recording, s")}};
}

api::Status PredictionRamp::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  const ParameterValues& v = in.values;
  b.Prepare("decouple", MotorMode::kDecoupled, 90.0, v.at("settle_s"));
  const model::SampledSignal envelope =
      model::MakeStimulus("prediction_ramp", Pick(v, {"max_ma", "up_s", "down_s"}));
  const int t = b.AddTrial(b.plan().protocol, MotorMode::kDecoupled);
  b.EnvelopeTrial(t, envelope, MotorMode::kDecoupled, 90.0, 0.0);
  return api::Status::Ok();
}

}  // namespace

std::unique_ptr<const Protocol> MakePredictionRamp() { return std::make_unique<PredictionRamp>(); }

}  // namespace fesbench::server::protocols::catalog
