// The `active_random_binary` protocol (docs/PROTOCOLS.md, `active_random_binary`).

#include "server/protocols/catalog/parameters.h"
#include "server/protocols/protocol_registry.h"

namespace fesbench::server::protocols::catalog {
namespace {

// Two dense random-binary trains with a rest between (§5.4.4).
class ActiveRandomBinary final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override { return {api::TrialKind::kActive}; }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
};

ProtocolDescription ActiveRandomBinary::Describe() const {
  return {
      .name = "active_random_binary",
      .version = 1,
      .title = "Active identification (RB1, RB2)",
      .description =
          "Decoupled: two denser 10 s random-binary trains (RB1, RB2) with a rest between "
          "(§5.4.4, Fig. 5-11).",
      .bench_mode = BenchMode::kDecoupled,
      .kind = ProtocolKind::kFreeSwing,
      .min_rest_s = 2.0,
      .parameters = {
          ThresholdMa(), MaxMa(), AmplitudeMa(0.6),
          Number("duration_s", "length of each train, s",
                 {.value = 10.0, .min = 2.0, .max = 120.0}),
          Count("rb1_seed", "seed of RB1", {.value = 1.0, .min = 0.0, .max = 4294967295.0}),
          Count("rb2_seed", "seed of RB2", {.value = 2.0, .min = 0.0, .max = 4294967295.0}),
          Rest("rest_s", "rest between the trains, s", {.value = 10.0, .min = 2.0, .max = 300.0}),
          SettleS(2.0, "swing after decoupling before recording, s")}};
}

api::Status ActiveRandomBinary::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  const ParameterValues& v = in.values;
  b.Prepare("decouple", MotorMode::kDecoupled, 90.0, v.at("settle_s"));
  const double amp = v.at("amplitude_ma");
  const int t1 = b.AddTrial("active_random_binary_rb1", MotorMode::kDecoupled);
  b.EnvelopeTrial(t1, RandomBinary(true, amp, v.at("duration_s"), v.at("rb1_seed")),
                  MotorMode::kDecoupled, 90.0, 0.0);
  b.Rest("rest between trains", v.at("rest_s"), in.min_rest_s, -1, MotorMode::kDecoupled, 90.0);
  const int t2 = b.AddTrial("active_random_binary_rb2", MotorMode::kDecoupled);
  b.EnvelopeTrial(t2, RandomBinary(true, amp, v.at("duration_s"), v.at("rb2_seed")),
                  MotorMode::kDecoupled, 90.0, 0.0);
  return api::Status::Ok();
}

}  // namespace

std::unique_ptr<const Protocol> MakeActiveRandomBinary() {
  return std::make_unique<ActiveRandomBinary>();
}

}  // namespace fesbench::server::protocols::catalog
