// The `daily_check` protocol (docs/PROTOCOLS.md, `daily_check`).

#include <memory>

#include "server/protocols/catalog/conclusions.h"
#include "server/protocols/catalog/parameters.h"
#include "server/protocols/daily_check_protocol.h"
#include "server/protocols/protocol_registry.h"

namespace fesbench::server::protocols::catalog {
namespace {

// Today's isometric ramp and a random-binary free swing (§7.6.4; daily_check_protocol.h judges
// them).
class DailyCheck final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override {
    return {api::TrialKind::kDailyCheckRamp, api::TrialKind::kDailyCheckSwing};
  }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
  api::RunOutcome Conclude(const RunConclusionInput& in, const RunResult& r) const override;
};

ProtocolDescription DailyCheck::Describe() const {
  return {
      .name = "daily_check",
      .version = 1,
      .title = "Daily check of the model",
      .description =
          "A short check of today's leg against its stored parameter set: knee locked, 2 "
          "impulses and one 4 s cosine ramp (pole, IRC by ramp correlation, full-scale torque), "
          "then a 4 s random-binary free swing that validates the outcome. Threshold, slope, "
          "full-scale torque and pole are compared with bounds learned from the leg's own "
          "history of sets; only what moved is re-fitted (a new version of the set), a moved "
          "pole calls for a full rapid run (§7.4.3).",
      .bench_mode = BenchMode::kMixed,
      .kind = ProtocolKind::kDailyCheck,
      .min_rest_s = 1.0,
      .parameters = {
          LockAngleDeg(), SettleS(0.8, "time to move to and lock the angle, s"), ThresholdMa(),
          MaxMa(),
          Count("impulses", "number of impulses at max", {.value = 2.0, .min = 1.0, .max = 20.0}),
          Number("below_threshold_ma", "ramp start below threshold, mA",
                 {.value = 5.0, .min = 0.0, .max = 50.0}),
          Number("ramp_duration_s", "whole ramp (half up, half down), s",
                 {.value = 4.0, .min = 0.5, .max = 30.0}),
          Rest("rest_s", "zero stimulation after each isometric element, s",
               {.value = 1.0, .min = 1.0, .max = 60.0}),
          AmplitudeMa(0.6),
          Number("swing_s", "random-binary free swing that validates the outcome, s",
                 {.value = 4.0, .min = 2.0, .max = 30.0}),
          Count("seed", "random seed of the swing's train",
                {.value = 5.0, .min = 0.0, .max = 4294967295.0}),
          Number("swing_settle_s", "swing after decoupling before the train, s",
                 {.value = 1.0, .min = 0.2, .max = 30.0})}};
}

api::Status DailyCheck::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  const ParameterValues& v = in.values;
  if (!in.subject.parameter_set) {
    return api::Status::FailedPrecondition(NoApprovedSetMessage(b.plan().protocol));
  }
  const double lock = v.at("lock_angle_deg");
  b.Prepare("lock", MotorMode::kLocked, lock, v.at("settle_s"));
  const int ramp = b.AddTrial("daily_check_ramp_irc", MotorMode::kLocked);
  model::GeneratorParams g = Pick(
      v, {"threshold_ma", "max_ma", "impulses", "below_threshold_ma", "ramp_duration_s", "rest_s"});
  g["conditioning_s"] = 0.0;
  g["ramps"] = 1.0;
  b.EnvelopeTrial(ramp, model::MakeStimulus("isometric_ramp_irc", g), MotorMode::kLocked, lock,
                  in.min_rest_s);
  b.Prepare("decouple", MotorMode::kDecoupled, lock, v.at("swing_settle_s"));
  const int swing = b.AddTrial("daily_check_swing", MotorMode::kDecoupled);
  b.EnvelopeTrial(swing, RandomBinary(true, v.at("amplitude_ma"), v.at("swing_s"), v.at("seed")),
                  MotorMode::kDecoupled, lock, 0.0);
  b.plan().analysis = std::make_shared<const DailyCheckEvaluation>(
      DailyCheckSettings{ramp, swing, lock});
  return api::Status::Ok();
}

// The leg's set it compared with, and its report (DailyCheckEvaluation's).
api::RunOutcome DailyCheck::Conclude(const RunConclusionInput& in, const RunResult& r) const {
  api::RunOutcome o = ConcludeWithLegSet(in, r);
  if (r.daily_check) {
    api::Result<api::DailyCheckOutcome> report = api::DailyCheckOutcomeFromJson(*r.daily_check);
    if (report.ok()) o.daily_check = *std::move(report);
  }
  return o;
}

}  // namespace

std::unique_ptr<const Protocol> MakeDailyCheck() { return std::make_unique<DailyCheck>(); }

}  // namespace fesbench::server::protocols::catalog
