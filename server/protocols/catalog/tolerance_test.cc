// The `tolerance_test` protocol (docs/PROTOCOLS.md, `tolerance_test`).

#include "server/protocols/catalog/parameters.h"
#include "server/protocols/protocol_registry.h"

namespace fesbench::server::protocols::catalog {
namespace {

// The amplitude ramp of the tolerance test on the locked knee (tolerance_detector.h stops it).
class ToleranceTest final : public Protocol {
 public:
  ProtocolDescription Describe() const override;
  std::vector<api::TrialKind> Records() const override { return {api::TrialKind::kToleranceTest}; }
  api::Status BuildSteps(const PlanInputs& in, PlanBuilder& b) const override;
  api::RunOutcome Conclude(const RunConclusionInput& in, const RunResult& r) const override;
};

ProtocolDescription ToleranceTest::Describe() const {
  return {
      .name = "tolerance_test",
      .version = 2,
      .title = "Stimulation tolerance test",
      .description =
          "Knee locked at 90°; the amplitude rises slowly from start_ma at rate_ma_per_s "
          "until the clinician stops, the subject signals the limit (a hand-held switch; the "
          "simulated subject does at its own max tolerated amplitude) or ceiling_ma. Records "
          "the threshold (first torque above the offset's noise band) and the max tolerated "
          "amplitude (where it was stopped). Appendix F part II.K, §5.2.1.",
      .bench_mode = BenchMode::kLocked,
      .kind = ProtocolKind::kTolerance,
      .min_rest_s = 0.0,
      .parameters =
          {LockAngleDeg(), SettleS(1.5, "time to move to and lock the angle, s"),
           Number("start_ma", "amplitude at the start of the ramp, mA",
                  {.value = 0.0, .min = 0.0, .max = 100.0}),
           Number("rate_ma_per_s", "amplitude rise rate, mA/s",
                  {.value = 0.5, .min = 0.05, .max = 5.0}),
           Number("ceiling_ma",
                  "amplitude where the ramp ends if not stopped, mA: the session's max tolerated "
                  "amplitude; 60 mA for a session without one. Above a recorded max only with an "
                  "explicit, audited ceiling_reason",
                  {.value = 60.0, .min = 1.0, .max = 100.0}, Scaling::kToleranceCeiling),
           Number("threshold_torque_nm", "torque above the offset taken as a response, N·m",
                  {.value = 0.5, .min = 0.05, .max = 10.0}),
           Number("min_torque_at_max_nm", "torque the subject must produce at max (warning), N·m",
                  {.value = 6.0, .min = 0.0, .max = 60.0})},
      .measures_max_tolerated = true};
}

api::Status ToleranceTest::BuildSteps(const PlanInputs& in, PlanBuilder& b) const {
  const ParameterValues& v = in.values;
  const double lock = v.at("lock_angle_deg");
  b.plan().max_stim_ma = v.at("ceiling_ma");
  b.plan().tolerance = ToleranceSettings{v.at("threshold_torque_nm"), v.at("min_torque_at_max_nm")};
  if (!(v.at("ceiling_ma") > v.at("start_ma"))) {
    return api::Status::InvalidArgument("ceiling_ma: must be above start_ma", "parameters");
  }
  b.Prepare("lock", MotorMode::kLocked, lock, v.at("settle_s"));
  const int t = b.AddTrial("tolerance_test", MotorMode::kLocked);
  b.Offset(t, MotorMode::kLocked, lock);
  Step s;
  s.phase = StepPhase::kStimulate;
  s.label = "raise amplitude";
  s.ticks = Ticks((v.at("ceiling_ma") - v.at("start_ma")) / v.at("rate_ma_per_s"));
  s.motor_mode = MotorMode::kLocked;
  s.setpoint_deg = lock;
  s.tolerance_ramp = true;
  s.ramp_start_ma = v.at("start_ma");
  s.ramp_ma_per_s = v.at("rate_ma_per_s");
  s.trial = t;
  b.Push(std::move(s));
  b.Rest("relax", 1.0, 0.0, t, MotorMode::kLocked, lock);
  return api::Status::Ok();
}

// docs/SAFETY.md, tolerance test ceiling: the ramp reaching its ceiling
// says only that the subject bore the ceiling, not where their limit is.
// Only a limit the subject signalled or the clinician stopped at is a
// measured max tolerated amplitude.
api::RunOutcome ToleranceTest::Conclude(const RunConclusionInput& in, const RunResult& r) const {
  api::RunOutcome o = ConcludeCommon(r);
  if (!r.tolerance) return o;
  const bool done = o.state == RunState::kDone;
  api::ToleranceOutcome t;
  t.test = *r.tolerance;
  t.threshold_ma = r.tolerance->threshold_ma;
  t.subject_signalled_limit = RunFlag(r, "subject_signalled_limit");
  t.ended_at_ceiling = done && !r.tolerance->stopped_by_clinician &&
                       !t.subject_signalled_limit.value_or(false);
  if (t.ended_at_ceiling) {
    t.message = CeilingMessage(in.parameters);
    t.test->warnings.push_back(t.message);
  } else {
    t.max_tolerated_ma = r.tolerance->max_tolerated_ma;
    if (done && !t.threshold_ma) {
      t.test->warnings.push_back(
          "no threshold was detected: the session's threshold and max tolerated are unchanged");
    }
  }
  o.tolerance = std::move(t);
  return o;
}

}  // namespace

std::unique_ptr<const Protocol> MakeToleranceTest() { return std::make_unique<ToleranceTest>(); }

}  // namespace fesbench::server::protocols::catalog
