// The `free_swing_passive` protocol (docs/PROTOCOLS.md, `free_swing_passive`).

#include "server/protocols/catalog/parameters.h"
#include "server/protocols/protocol_registry.h"

namespace fesbench::server::protocols::catalog {
namespace {

// One sparse random-binary train on the decoupled knee (§5.4.3).
class FreeSwingPassive final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override {
    return {api::TrialKind::kFreeSwingPassive};
  }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
};

ProtocolDescription FreeSwingPassive::Describe() const {
  return {.name = "free_swing_passive",
          .version = 1,
          .title = "Free-swing passive identification",
          .description =
              "Decoupled: a 10 s sparse random-binary train at the amplitude that just reaches "
              "full extension; position and acceleration at 200 Hz (§5.4.3, Fig. 5-10).",
          .bench_mode = BenchMode::kDecoupled,
          .kind = ProtocolKind::kFreeSwing,
          .min_rest_s = 0.0,
          .parameters = {
              ThresholdMa(), MaxMa(), AmplitudeMa(0.6),
              Number("duration_s", "train length, s", {.value = 10.0, .min = 3.0, .max = 120.0}),
              Count("seed", "random seed of the train",
                    {.value = 1.0, .min = 0.0, .max = 4294967295.0}),
              SettleS(2.0, "swing after decoupling before recording, s")}};
}

api::Status FreeSwingPassive::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  const ParameterValues& v = in.values;
  b.Prepare("decouple", MotorMode::kDecoupled, 90.0, v.at("settle_s"));
  const int t = b.AddTrial(b.plan().protocol, MotorMode::kDecoupled);
  b.EnvelopeTrial(t, RandomBinary(false, v.at("amplitude_ma"), v.at("duration_s"), v.at("seed")),
                  MotorMode::kDecoupled, 90.0, 0.0);
  return api::Status::Ok();
}

}  // namespace

std::unique_ptr<const Protocol> MakeFreeSwingPassive() {
  return std::make_unique<FreeSwingPassive>();
}

}  // namespace fesbench::server::protocols::catalog
