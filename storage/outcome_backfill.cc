// Migration 19's backfill (storage/migrations.h): the outcome of each run that
// ended before runs stored one, derived once the way the software of schema
// 18 derived it when it showed the run (docs/ARCHITECTURE.md, "Runs"): the
// session revision a done tolerance_test wrote, found by the reason it gave
// the revision ("tolerance_test run N"); the set a done run stored, by the
// run it names (schema 13) or, for rapid_parameterisation and daily_check
// runs before that, by its provenance naming only the run's trials.

#include <optional>
#include <string>
#include <vector>

#include "api/run_outcome.h"
#include "api/run_state.h"
#include "storage/migrations.h"
#include "storage/row_helpers.h"

namespace fesbench::storage {
namespace {

struct EndedRun {
  std::int64_t event_id = 0;
  std::int64_t run_id = 0;
  api::RunState state = api::RunState::kFailed;
  std::string message;
  std::string protocol;
};

api::Result<std::vector<EndedRun>> EndedRunsWithoutOutcome(Connection& c) {
  return internal::QueryRows(
      c,
      "SELECT e.id, e.run_id, e.state, e.message, r.protocol_name FROM run_events e"
      " JOIN runs r ON r.id = e.run_id"
      " WHERE e.outcome_json IS NULL AND e.state IN ('done', 'failed', 'aborted')"
      " AND e.id = (SELECT MAX(x.id) FROM run_events x WHERE x.run_id = e.run_id)"
      " ORDER BY e.id",
      [](const Statement& s) -> api::Result<EndedRun> {
        EndedRun r;
        r.event_id = s.Int64(0);
        r.run_id = s.Int64(1);
        const auto state = api::ParseRunState(s.Text(2));
        if (!state) return internal::BadStoredValue("run event");
        r.state = *state;
        r.message = s.Text(3);
        r.protocol = s.Text(4);
        return r;
      });
}

api::Result<std::optional<std::int64_t>> FirstId(
    api::Result<std::vector<std::int64_t>> ids) {
  if (!ids.ok()) return ids.status();
  if (ids->empty()) return std::optional<std::int64_t>();
  return std::optional<std::int64_t>(ids->front());
}

// The set a done run stored: by its run_id, else (rapid_parameterisation,
// daily_check) the leg's first set since the run was created whose
// provenance trials are all the run's.
api::Result<std::optional<std::int64_t>> StoredSetOf(Connection& c, const EndedRun& run) {
  const auto id = [](const Statement& s) { return s.Int64(0); };
  auto by_run = FirstId(internal::QueryRows(
      c, "SELECT id FROM parameter_sets WHERE run_id = ?1 ORDER BY id DESC LIMIT 1", id,
      run.run_id));
  if (!by_run.ok() || *by_run) return by_run;
  if (run.protocol != "rapid_parameterisation" && run.protocol != "daily_check") return by_run;
  return FirstId(internal::QueryRows(
      c,
      "SELECT ps.id FROM parameter_sets ps JOIN runs r ON r.id = ?1"
      " JOIN sessions s ON s.id = r.session_id"
      " WHERE ps.subject_id = s.subject_id AND ps.leg_id = s.leg_id"
      " AND ps.created_at_utc >= r.created_at_utc"
      " AND EXISTS (SELECT 1 FROM parameter_set_trials p WHERE p.parameter_set_id = ps.id)"
      " AND NOT EXISTS (SELECT 1 FROM parameter_set_trials p WHERE p.parameter_set_id = ps.id"
      "   AND p.trial_id NOT IN (SELECT t.id FROM trials t WHERE t.run_id = r.id))"
      " ORDER BY ps.created_at_utc, ps.id LIMIT 1",
      id, run.run_id));
}

// A done tolerance_test's revision: the last one whose reason names the run.
api::Status AddToleranceRevision(Connection& c, const EndedRun& run, api::RunOutcome& outcome) {
  struct Revision {
    int number = 0;
    std::optional<double> threshold_ma, max_tolerated_ma;
  };
  auto revisions = internal::QueryRows(
      c,
      "SELECT sr.revision, sr.threshold_ma, sr.max_tolerated_ma FROM session_revisions sr"
      " JOIN runs r ON r.session_id = sr.session_id WHERE r.id = ?1 AND sr.reason = ?2"
      " ORDER BY sr.revision DESC LIMIT 1",
      [](const Statement& s) {
        Revision r;
        r.number = static_cast<int>(s.Int64(0));
        if (!s.IsNull(1)) r.threshold_ma = s.Double(1);
        if (!s.IsNull(2)) r.max_tolerated_ma = s.Double(2);
        return r;
      },
      run.run_id, "tolerance_test run " + std::to_string(run.run_id));
  if (!revisions.ok()) return revisions.status();
  if (revisions->empty()) return api::Status::Ok();
  const Revision& r = revisions->front();
  outcome.session_revision = r.number;
  api::ToleranceOutcome t;
  t.threshold_ma = r.threshold_ma;
  t.max_tolerated_ma = r.max_tolerated_ma;
  outcome.tolerance = std::move(t);
  return api::Status::Ok();
}

api::Result<api::RunOutcome> OutcomeOf(Connection& c, const EndedRun& run) {
  api::RunOutcome outcome;
  outcome.state = run.state;
  if (run.state != api::RunState::kDone) {
    outcome.reason = run.message;
    return outcome;
  }
  auto set = StoredSetOf(c, run);
  if (!set.ok()) return set.status();
  outcome.parameter_set_id = *set;
  if (!*set && run.protocol == "tolerance_test") {
    if (auto s = AddToleranceRevision(c, run, outcome); !s.ok()) return s;
  }
  return outcome;
}

}  // namespace

api::Status BackfillRunOutcomes(Connection& c) {
  auto ended = EndedRunsWithoutOutcome(c);
  if (!ended.ok()) return ended.status();
  for (const EndedRun& run : *ended) {
    auto outcome = OutcomeOf(c, run);
    if (!outcome.ok()) return outcome.status();
    if (auto s = internal::Execute(c, "UPDATE run_events SET outcome_json = ?1 WHERE id = ?2",
                                   api::RunOutcomeToJson(*outcome).dump(), run.event_id);
        !s.ok()) {
      return s;
    }
  }
  return api::Status::Ok();
}

}  // namespace fesbench::storage
