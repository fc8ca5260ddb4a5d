#include "server/services/run_service.h"

#include <algorithm>

#include "model/identify_passive_only.h"
#include "storage/parameter_sets.h"
#include "storage/sessions.h"
#include "storage/subjects.h"
#include "storage/trials.h"

namespace fesbench::server::services {

namespace {

// The leg's approved set (docs/SAFETY.md: the set a clinician approved, not
// the newest row), the sets approved before it, and the ramp it came from.
api::Status LoadApprovedSet(storage::Database& db, const storage::Session& session,
                            SessionContext& out) {
  protocols::SubjectContext& c = out.subject;
  storage::ParameterSetRepository sets(db);
  api::Result<storage::StoredParameterSet> approved = sets.Approved(session.leg_id);
  if (!approved.ok()) {
    if (approved.status().code() != api::ErrorCode::kNotFound) return approved.status();
    // A set awaits approval if one could be approved: passive-only sets
    // (model::IsPassiveOnly) never can, and do not hold back the leg.
    storage::ParameterSetListQuery query;
    query.subject_id = session.subject_id;
    query.leg_id = session.leg_id;
    query.limit = 200;
    for (;;) {
      api::Result<std::vector<storage::ParameterSetSummary>> page = sets.List(query);
      if (!page.ok()) return page.status();
      for (const storage::ParameterSetSummary& set : *page) {
        if (set.irc_method != model::kNotIdentified && set.active_method != model::kNotIdentified) {
          c.sets_await_approval = true;
          return api::Status::Ok();
        }
      }
      if (page->size() < query.limit) return api::Status::Ok();
      query.after_id = page->back().id;
    }
  }
  c.parameter_set = approved->params;
  c.parameter_set_id = approved->summary.id;
  out.parameter_set_id = approved->summary.id;
  // The leg's approved history, newest first (daily_check's drift bounds).
  api::Result<std::vector<std::int64_t>> history = sets.ApprovedHistory(session.leg_id, 20);
  if (!history.ok()) return history.status();
  for (std::int64_t id : *history) {
    api::Result<storage::StoredParameterSet> s = sets.Get(id);
    if (s.ok()) c.history.push_back(s->params);
  }
  storage::TrialRepository trials(db);
  for (std::int64_t id : approved->trial_ids) {
    api::Result<api::Trial> t = trials.Get(id);
    if (!t.ok()) continue;
    if (t->kind == api::TrialKind::kRapidRamp || t->kind == api::TrialKind::kDailyCheckRamp) {
      c.base_ramp_trial = api::ToTrialColumns(*t);
      break;
    }
  }
  return api::Status::Ok();
}

}  // namespace

api::Result<SessionContext> LoadSessionContext(storage::Database& db, std::int64_t session_id,
                                               const BenchLimits& limits) {
  api::Result<storage::Session> session = storage::SessionRepository(db).Get(session_id);
  if (!session.ok()) return session.status();
  api::Result<storage::Subject> subject = storage::SubjectRepository(db).Get(session->subject_id);
  if (!subject.ok()) return subject.status();

  SessionContext out;
  out.session = *session;
  protocols::SubjectContext& c = out.subject;
  const storage::SessionDetails& d = session->current.details;
  out.has_stimulation_limits = d.threshold_ma.has_value() && d.max_tolerated_ma.has_value();
  // Without recorded limits only tolerance_test may run (it measures them):
  // without a recorded max, the stimulator's range, which the test's
  // ceiling_ma bounds; with one, the recorded max bounds the test too.
  c.threshold_ma = d.threshold_ma.value_or(0.0);
  c.max_tolerated_recorded = d.max_tolerated_ma.has_value();
  c.max_tolerated_ma = c.max_tolerated_recorded ? *d.max_tolerated_ma : limits.max_stim_ma;
  // The range of motion: the bench's mechanical range, narrowed by the
  // subject's recorded one (docs/SAFETY.md); the safety layer enforces it.
  const storage::SubjectDetails& a = subject->current.details;
  c.min_angle_deg = std::max(limits.min_angle_deg, a.rom_min_deg.value_or(limits.min_angle_deg));
  c.max_angle_deg = std::min(limits.max_angle_deg, a.rom_max_deg.value_or(limits.max_angle_deg));
  // Eq. 4.13, §4.2.1: body mass and the femoral condyle–medial malleolus
  // length (the shank length) give the inertia when no prior set does.
  if (a.weight_kg) c.body_mass_kg = *a.weight_kg;
  if (a.shank_length_cm) c.leg_length_m = *a.shank_length_cm / 100.0;

  if (api::Status st = LoadApprovedSet(db, *session, out); !st.ok()) return st;
  return out;
}

}  // namespace fesbench::server::services
