#pragma once

// What the strength-in-a-session test and its by-hand study share
// (docs/MODEL.md, "The strength at a trial's start"): a recorded trial's
// stimulation, whether it is a stimulated free swing, and the E_RMS of a
// free-swing prediction from its measured start as POST /predictions
// computes it.

#include <algorithm>
#include <optional>
#include <vector>

#include "api/trial_kind.h"
#include "model/conditioning.h"
#include "model/evaluation.h"
#include "model/strength_history.h"
#include "server/protocols/model_gate.h"
#include "server/protocols/runner.h"

namespace fesbench::server::protocols::test {

/// A recorded trial's pulses and bench start time.
inline model::StimulationRecord Record(const RecordedTrial& t) {
  model::StimulationRecord r;
  r.start_s = t.bench_start_s;
  if (t.trial.pulses) {
    r.pulses = t.trial.pulses->Train();
    r.pulse_rate_hz = t.trial.pulses->pulse_rate_hz;
  }
  return r;
}

/// A free swing with stimulation (not knee-locked, no motor, pulses kept).
inline bool IsFreeSwing(const RecordedTrial& t) {
  const api::TrialKindInfo* k = api::FindTrialKind(t.trial.name.value_or(""));
  return k != nullptr && !k->knee_locked && !k->motor && t.trial.pulses;
}

/// E_RMS of a free-swing prediction from the trial's measured start.
inline double Erms(const model::ParameterSet& set, const RecordedTrial& t,
            std::optional<model::SimulationStrength> strength) {
  const std::vector<double>& angle = *t.trial.Values("angle_deg");
  const std::vector<double>& ts = *t.trial.Values("t_s");
  model::SimulationOptions o;
  o.initial_angle_deg = std::clamp(angle.front(), 10.0, 110.0);
  o.initial_velocity_deg_s = model::GcvSmoothingSpline(ts, angle).first.front();
  o.output_rate_hz = t.trial.sample_rate_hz;
  o.duration_s = (static_cast<double>(angle.size()) + 0.5) / t.trial.sample_rate_hz;
  o.pulse_rate_hz = t.trial.pulses->pulse_rate_hz;
  o.joint_limits = model::JointLimits{};
  o.strength = std::move(strength);
  const model::SimulationResult sim = SimulateStimulatedSwing(set, t.trial.pulses->Train(), o);
  std::vector<double> p(angle.size());
  for (std::size_t i = 0; i < angle.size(); ++i) p[i] = sim.angle_deg[std::min(i, sim.size() - 1)];
  return model::RmsError(p, angle);
}

}  // namespace fesbench::server::protocols::test
