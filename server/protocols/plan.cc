#include "server/protocols/plan.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "server/protocols/plan_builder.h"
#include "server/protocols/protocol_registry.h"

// The generic step builders (plan_builder.h) and BuildPlan, which hands a
// protocol's plan to its class (protocol_registry.h, docs/PROTOCOLS.md).

namespace fesbench::server::protocols {

std::int64_t Ticks(double s) {
  return static_cast<std::int64_t>(std::llround(s * kTicksPerSecond));
}

model::GeneratorParams Pick(const ParameterValues& v, std::initializer_list<const char*> names) {
  model::GeneratorParams out;
  for (const char* n : names) {
    if (const auto it = v.find(n); it != v.end()) out[n] = it->second;
  }
  return out;
}

model::SampledSignal RandomBinary(bool dense, double amplitude_ma, double duration_s, double seed) {
  return model::MakeStimulus(
      dense ? "random_binary_dense" : "random_binary_sparse",
      {{"amplitude_ma", amplitude_ma}, {"duration_s", duration_s}, {"seed", seed}});
}

int PlanBuilder::AddTrial(std::string name, MotorMode mode, bool setpoint) {
  plan_.trials.push_back({std::move(name), mode, setpoint});
  return static_cast<int>(plan_.trials.size()) - 1;
}

void PlanBuilder::Prepare(std::string label, MotorMode mode, double angle_deg, double settle_s,
                          bool move_from_current) {
  Step s;
  s.phase = StepPhase::kPrepare;
  s.label = std::move(label);
  s.ticks = Ticks(settle_s);
  s.motor_mode = mode;
  s.setpoint_deg = angle_deg;
  s.move_from_current = move_from_current;
  Push(std::move(s));
}

void PlanBuilder::Offset(int trial, MotorMode mode, double angle_deg) {
  Step s;
  s.phase = StepPhase::kOffset;
  s.label = "offset";
  s.ticks = kOffsetSamples;
  s.motor_mode = mode;
  s.setpoint_deg = angle_deg;
  s.trial = trial;
  Push(std::move(s));
}

void PlanBuilder::Rest(std::string label, double rest_s, double min_rest_s, int trial,
                       MotorMode mode, double angle_deg) {
  Step s;
  s.phase = StepPhase::kRest;
  s.label = std::move(label);
  s.ticks = Ticks(std::max(rest_s, min_rest_s));
  s.motor_mode = mode;
  s.setpoint_deg = angle_deg;
  s.trial = trial;
  s.min_rest_s = min_rest_s;
  Push(std::move(s));
}

/// A recorded stimulation envelope: the offset lead, then its runs of
/// stimulation (kStimulate) and of zero (kRest, whose last 50 ms before
/// the next stimulation is a fresh torque offset, kOffset).
void PlanBuilder::EnvelopeTrial(int trial, const model::SampledSignal& envelope, MotorMode mode,
                                double angle_deg, double min_rest_s) {
  Offset(trial, mode, angle_deg);
  auto env = std::make_shared<const model::SampledSignal>(envelope);
  const std::vector<double>& v = env->values;
  std::size_t i = 0;
  while (i < v.size()) {
    const bool on = v[i] > 0.0;
    std::size_t j = i;
    while (j < v.size() && (v[j] > 0.0) == on) ++j;
    const std::int64_t begin = static_cast<std::int64_t>(i) * kTicksPerSample;
    const std::int64_t len = static_cast<std::int64_t>(j - i) * kTicksPerSample;
    const auto piece = [&](StepPhase phase, std::int64_t from, std::int64_t ticks) {
      if (ticks <= 0) return;
      Step s;
      s.phase = phase;
      s.label = phase == StepPhase::kStimulate ? "stimulate"
                : phase == StepPhase::kOffset  ? "offset"
                                               : "rest";
      s.ticks = ticks;
      s.motor_mode = mode;
      s.setpoint_deg = angle_deg;
      s.envelope = env;
      s.stim_offset_ticks = from;
      s.trial = trial;
      if (phase == StepPhase::kRest) s.min_rest_s = std::min(min_rest_s, ticks / 1000.0);
      Push(std::move(s));
    };
    if (on) {
      piece(StepPhase::kStimulate, begin, len);
    } else if (j < v.size() && len >= 2 * kOffsetSamples) {
      piece(StepPhase::kRest, begin, len - kOffsetSamples);
      piece(StepPhase::kOffset, begin + len - kOffsetSamples, kOffsetSamples);
    } else {
      piece(StepPhase::kRest, begin, len);
    }
    i = j;
  }
}

void PlanBuilder::Move(std::string label, std::shared_ptr<const model::Trajectory> trajectory,
                       int trial) {
  Step s;
  s.phase = StepPhase::kMove;
  s.label = std::move(label);
  s.ticks = Ticks(trajectory->duration_s());
  s.motor_mode = MotorMode::kPosition;
  s.setpoint_deg = trajectory->At(trajectory->duration_s()).angle_deg;
  s.trajectory = std::move(trajectory);
  s.trial = trial;
  Push(std::move(s));
}

void PlanBuilder::MoveTo(std::string label, double angle_deg, double move_s, int trial) {
  Step s;
  s.phase = StepPhase::kMove;
  s.label = std::move(label);
  s.ticks = Ticks(move_s);
  s.motor_mode = MotorMode::kPosition;
  s.setpoint_deg = angle_deg;
  s.move_from_current = true;
  s.trial = trial;
  Push(std::move(s));
}

void PlanBuilder::Push(Step s) {
  if (s.ticks > 0) plan_.steps.push_back(std::move(s));
}

std::int64_t Plan::total_ticks() const {
  std::int64_t n = 0;
  for (const Step& s : steps) n += s.ticks;
  return n;
}

api::Result<Plan> BuildPlan(const ProtocolDescription& protocol, const ParameterValues& values,
                            const SubjectContext& subject,
                            const std::vector<double>& uploaded_target,
                            const ParameterValues* given) {
  Plan plan;
  plan.protocol = protocol.name;
  plan.protocol_version = protocol.version;
  plan.kind = protocol.kind;
  plan.parameters = values;
  plan.max_stim_ma = subject.max_tolerated_ma;
  const RegisteredProtocol* registered = FindRegisteredProtocol(protocol.name);
  if (registered == nullptr) return api::Status::NotFound("no plan for protocol " + protocol.name);
  PlanBuilder builder(plan);
  const PlanInputs inputs{values, subject, uploaded_target, given, protocol.min_rest_s};
  try {
    if (api::Status st = registered->protocol->BuildSteps(inputs, builder); !st.ok()) return st;
  } catch (const std::out_of_range& e) {
    return api::Status::InvalidArgument(std::string("parameters not resolved: ") + e.what(),
                                        "parameters");
  } catch (const std::invalid_argument& e) {
    return api::Status::InvalidArgument(e.what(), "parameters");
  }
  return plan;
}

api::Result<Plan> MakePlan(std::string_view protocol, const ParameterValues& values,
                           const SubjectContext& subject,
                           const std::vector<double>& uploaded_target) {
  const ProtocolDescription* p = FindProtocol(protocol);
  if (p == nullptr) return api::Status::NotFound("unknown protocol " + std::string(protocol));
  api::Result<ParameterValues> resolved = ResolveParameters(*p, values, subject);
  if (!resolved.ok()) return resolved.status();
  return BuildPlan(*p, *resolved, subject, uploaded_target, &values);
}

model::SampledSignal TrialEnvelope(const Plan& plan, int trial) {
  model::SampledSignal out;
  out.rate_hz = 200.0;
  for (const Step& s : plan.steps) {
    if (s.trial != trial) continue;
    const std::int64_t samples = s.ticks / kTicksPerSample;
    for (std::int64_t k = 0; k < samples; ++k) {
      double u = 0.0;
      if (s.envelope) {
        const std::int64_t idx = (s.stim_offset_ticks + k * kTicksPerSample) / kTicksPerSample;
        if (idx >= 0 && idx < static_cast<std::int64_t>(s.envelope->values.size())) {
          u = s.envelope->values[static_cast<std::size_t>(idx)];
        }
      }
      out.values.push_back(u);
    }
  }
  return out;
}

}  // namespace fesbench::server::protocols
