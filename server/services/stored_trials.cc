#include "server/services/stored_trials.h"

#include <algorithm>
#include <stdexcept>
#include <vector>

#include "model/identify_rapid.h"

#include "storage/sessions.h"
#include "storage/trials.h"

namespace fesbench::server::services {

api::Result<LoadedTrial> LoadTrial(storage::Database& db, std::int64_t trial_id) {
  return db.Read([&](storage::Connection&) -> api::Result<LoadedTrial> {
    storage::TrialRepository trials(db);
    api::Result<api::Trial> trial = trials.Get(trial_id);
    if (!trial.ok()) return trial.status();
    api::Result<storage::TrialOwner> owner = trials.Owner(trial_id);
    if (!owner.ok()) return owner.status();
    api::Result<storage::Session> session = storage::SessionRepository(db).Get(owner->session_id);
    if (!session.ok()) return session.status();
    LoadedTrial out;
    out.id = trial_id;
    out.session_id = session->id;
    out.subject_id = session->subject_id;
    out.leg_id = session->leg_id;
    out.trial = std::move(trial).value();
    return out;
  });
}

model::PulseTrain TrialStimulation(const api::Trial& trial, const model::TrialColumns& columns,
                                   double default_rate_hz, double& pulse_rate_hz) {
  if (!trial.pulses) {
    pulse_rate_hz = default_rate_hz;
    return model::TrialPulses(columns, default_rate_hz);
  }
  pulse_rate_hz = trial.pulses->pulse_rate_hz;
  const double t0 = columns.t_s.empty() ? 0.0 : columns.t_s.front();
  model::PulseTrain out;
  out.reserve(trial.pulses->size());
  for (const model::Pulse& p : trial.pulses->Train()) {
    // A pulse within round-off before the first sample is at it.
    const double t = p.t_s - t0;
    if (t < -model::kPulseTimeToleranceS) continue;
    double at = std::max(t, 0.0);
    // Two pulses read back at one instant are both replayed, 1 ns apart
    // (the model wants strictly increasing times).
    if (!out.empty() && at <= out.back().t_s) at = out.back().t_s + model::kPulseTimeToleranceS;
    out.push_back({at, p.stim_ma});
  }
  return out;
}

}  // namespace fesbench::server::services
