// The `prediction_random_binary` protocol (docs/PROTOCOLS.md, `prediction_random_binary`).

#include "server/protocols/catalog/conclusions.h"
#include "server/protocols/catalog/parameters.h"
#include "server/protocols/protocol_registry.h"

namespace fesbench::server::protocols::catalog {
namespace {

// Decoupled at 90°; one recorded stimulation envelope, the trial named after the protocol.
class PredictionRandomBinary final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override {
    return {api::TrialKind::kPredictionRandomBinary};
  }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
  // The set it is gated by (docs/SAFETY.md, model gate).
  api::RunOutcome Conclude(const RunConclusionInput& in, const RunResult& r) const override {
    return ConcludeWithLegSet(in, r);
  }
};

ProtocolDescription PredictionRandomBinary::Describe() const {
  return {.name = "prediction_random_binary",
          .version = 1,
          .title = "Knee angle prediction: random binary",
          .description =
              "Decoupled: a random-binary train like the active identification's (§5.4.5: "
              "\"the random binary stimulation patterns … were also used\").",
          .bench_mode = BenchMode::kDecoupled,
          .kind = ProtocolKind::kPrediction,
          .min_rest_s = 0.0,
          .parameters = {
              ThresholdMa(), MaxMa(), AmplitudeMa(0.6),
              Number("duration_s", "train length, s", {.value = 10.0, .min = 2.0, .max = 120.0}),
              Count("seed", "random seed of the train",
                    {.value = 3.0, .min = 0.0, .max = 4294967295.0}),
              Count("dense", "1 = dense (active) train, 0 = sparse (passive) train",
                    {.value = 1.0, .min = 0.0, .max = 1.0}),
              SettleS(2.0, "swing after decoupling before recording, s")}};
}

api::Status PredictionRandomBinary::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  const ParameterValues& v = in.values;
  b.Prepare("decouple", MotorMode::kDecoupled, 90.0, v.at("settle_s"));
  const model::SampledSignal envelope =
      RandomBinary(v.at("dense") != 0.0, v.at("amplitude_ma"), v.at("duration_s"), v.at("seed"));
  const int t = b.AddTrial(b.plan().protocol, MotorMode::kDecoupled);
  b.EnvelopeTrial(t, envelope, MotorMode::kDecoupled, 90.0, 0.0);
  return api::Status::Ok();
}

}  // namespace

std::unique_ptr<const Protocol> MakePredictionRandomBinary() {
  return std::make_unique<PredictionRandomBinary>();
}

}  // namespace fesbench::server::protocols::catalog
