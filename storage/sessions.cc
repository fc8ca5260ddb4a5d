#include "storage/sessions.h"

#include <charconv>
#include <cmath>
#include <nlohmann/json.hpp>

#include "storage/row_helpers.h"

namespace fesbench::storage {
namespace {

constexpr std::string_view kRevisionColumns =
    "r.id, r.revision, r.session_date, r.accelerometer_placement, r.threshold_ma,"
    " r.max_tolerated_ma, r.notes, r.corrects_id, r.reason, r.recorded_at_utc, r.recorded_by";

api::Result<SessionRevision> ReadRevision(const Statement& s, int first) {
  SessionRevision revision;
  revision.id = s.Int64(first);
  revision.revision = static_cast<int>(s.Int64(first + 1));
  revision.details.date = s.Text(first + 2);
  revision.details.accelerometer_placement = s.Text(first + 3);
  revision.details.threshold_ma = s.OptionalDouble(first + 4);
  revision.details.max_tolerated_ma = s.OptionalDouble(first + 5);
  revision.details.notes = s.Text(first + 6);
  revision.corrects_id = s.OptionalInt64(first + 7);
  revision.reason = s.Text(first + 8);
  const auto recorded = api::ParseUtc(s.Text(first + 9));
  if (!recorded) return internal::BadStoredValue("session revision");
  revision.recorded_at = *recorded;
  revision.recorded_by = s.Text(first + 10);
  return revision;
}

// The sessions with their latest revision: `where` selects on s.
api::Result<std::vector<Session>> QuerySessions(Connection& c, std::string_view where,
                                                std::int64_t id) {
  const std::string sql =
      "SELECT s.id, s.subject_id, s.leg_id, s.created_at_utc, " + std::string(kRevisionColumns) +
      " FROM sessions s JOIN session_revisions r ON r.session_id = s.id"
      " AND r.revision = (SELECT MAX(revision) FROM session_revisions WHERE session_id = s.id) " +
      std::string(where) + " ORDER BY s.id";
  return internal::QueryRows(
      c, sql,
      [](const Statement& s) -> api::Result<Session> {
        Session session;
        session.id = s.Int64(0);
        session.subject_id = s.Int64(1);
        session.leg_id = s.Int64(2);
        const auto created = api::ParseUtc(s.Text(3));
        auto revision = ReadRevision(s, 4);
        if (!created) return internal::BadStoredValue("session");
        if (!revision.ok()) return revision.status();
        session.created_at = *created;
        session.current = std::move(*revision);
        return session;
      },
      id);
}

api::Result<Session> GetSession(Connection& c, std::int64_t id) {
  return internal::One(QuerySessions(c, "WHERE s.id = ?1", id), "session", id);
}

api::Status InsertRevision(Connection& c, std::int64_t session_id, int revision,
                           const SessionDetails& d, std::optional<std::int64_t> corrects_id,
                           std::string_view reason, std::string_view recorded_by, api::UtcTime now) {
  return internal::Execute(
      c,
      "INSERT INTO session_revisions (session_id, revision, session_date,"
      " accelerometer_placement, threshold_ma, max_tolerated_ma, notes, corrects_id, reason,"
      " recorded_at_utc, recorded_by) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)",
      session_id, revision, d.date, d.accelerometer_placement, d.threshold_ma, d.max_tolerated_ma,
      d.notes, corrects_id, reason, api::FormatUtc(now), recorded_by);
}

api::Status CheckCurrent(const std::optional<double>& value, const char* field) {
  if (value && (!std::isfinite(*value) || *value < 0 || *value > 100)) {
    return api::Status::InvalidArgument(std::string(field) + " must be in [0, 100] mA", field);
  }
  return api::Status::Ok();
}

constexpr std::string_view kRunSql =
    "SELECT r.id, r.session_id, r.protocol_name, r.protocol_version, r.parameters_json,"
    " r.created_at_utc, r.bench_id,"
    " (SELECT state FROM run_events WHERE run_id = r.id ORDER BY id DESC LIMIT 1),"
    " (SELECT message FROM run_events WHERE run_id = r.id ORDER BY id DESC LIMIT 1),"
    " (SELECT MIN(at_utc) FROM run_events WHERE run_id = r.id AND state = 'running'),"
    " (SELECT MAX(at_utc) FROM run_events WHERE run_id = r.id"
    "    AND state IN ('done', 'failed', 'aborted')),"
    " (SELECT bench_s FROM run_events WHERE run_id = r.id ORDER BY id DESC LIMIT 1),"
    " (SELECT bench_planned_s FROM run_events WHERE run_id = r.id ORDER BY id DESC LIMIT 1),"
    " (SELECT outcome_json FROM run_events WHERE run_id = r.id ORDER BY id DESC LIMIT 1)"
    " FROM runs r ";

template <typename... Values>
api::Result<std::vector<Run>> QueryRuns(Connection& c, std::string_view where,
                                        const Values&... values) {
  return internal::QueryRows(
      c, std::string(kRunSql) + std::string(where),
      [](const Statement& s) -> api::Result<Run> {
        Run run;
        run.id = s.Int64(0);
        run.session_id = s.Int64(1);
        run.protocol_name = s.Text(2);
        run.protocol_version = s.Text(3);
        run.parameters_json = s.Text(4);
        const auto created = api::ParseUtc(s.Text(5));
        run.bench_id = s.Text(6);
        const auto state = api::ParseRunState(s.Text(7));
        if (!created || !state) return internal::BadStoredValue("run");
        run.created_at = *created;
        run.state = *state;
        run.message = s.Text(8);
        if (!s.IsNull(9)) run.started_at = api::ParseUtc(s.Text(9));
        if (!s.IsNull(10)) run.finished_at = api::ParseUtc(s.Text(10));
        if (!s.IsNull(11)) run.bench_s = s.Double(11);
        if (!s.IsNull(12)) run.bench_planned_s = s.Double(12);
        if (!s.IsNull(13)) {
          const nlohmann::json stored = nlohmann::json::parse(s.Text(13), nullptr, false);
          api::Result<api::RunOutcome> outcome = api::RunOutcomeFromJson(stored);
          if (!outcome.ok()) return internal::BadStoredValue("run outcome");
          run.outcome = *std::move(outcome);
        }
        return run;
      },
      values...);
}

api::Result<Run> GetRunIn(Connection& c, std::int64_t id) {
  return internal::One(QueryRuns(c, "WHERE r.id = ?1", id), "run", id);
}

api::Status AppendRunEvent(Connection& c, std::int64_t run_id, RunState state,
                           std::string_view message, api::UtcTime now,
                           const std::optional<RunBenchTime>& bench = std::nullopt,
                           const api::RunOutcome* outcome = nullptr) {
  if (outcome != nullptr) {
    const std::string outcome_json = api::RunOutcomeToJson(*outcome).dump();
    if (!bench) {
      return internal::Execute(c,
                               "INSERT INTO run_events (run_id, state, message, at_utc,"
                               " outcome_json) VALUES (?1, ?2, ?3, ?4, ?5)",
                               run_id, api::RunStateName(state), message, api::FormatUtc(now),
                               outcome_json);
    }
    return internal::Execute(c,
                             "INSERT INTO run_events (run_id, state, message, at_utc, bench_s,"
                             " bench_planned_s, outcome_json) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
                             run_id, api::RunStateName(state), message, api::FormatUtc(now),
                             bench->ran_s, bench->planned_s, outcome_json);
  }
  if (bench) {
    return internal::Execute(c,
                             "INSERT INTO run_events (run_id, state, message, at_utc, bench_s,"
                             " bench_planned_s) VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
                             run_id, api::RunStateName(state), message, api::FormatUtc(now),
                             bench->ran_s, bench->planned_s);
  }
  return internal::Execute(
      c, "INSERT INTO run_events (run_id, state, message, at_utc) VALUES (?1, ?2, ?3, ?4)", run_id,
      api::RunStateName(state), message, api::FormatUtc(now));
}

}  // namespace

api::RunView RunViewOf(const Run& run) {
  api::RunView v;
  v.run_id = run.id;
  v.session_id = run.session_id;
  v.protocol = run.protocol_name;
  const std::string& version = run.protocol_version;
  if (std::from_chars(version.data(), version.data() + version.size(), v.protocol_version).ec !=
      std::errc()) {
    v.protocol_version = 0;
  }
  const nlohmann::json params = nlohmann::json::parse(run.parameters_json, nullptr, false);
  if (params.is_object()) {
    for (const auto& [k, x] : params.items()) {
      if (x.is_number()) v.parameters[k] = x.get<double>();
    }
  }
  v.used_parameter_set_id = api::UsedParameterSetOf(v.parameters);
  v.state = run.state;
  if (v.state == RunState::kFailed || v.state == RunState::kAborted) v.reason = run.message;
  v.created_at = run.created_at;
  v.started_at = run.started_at;
  v.finished_at = run.finished_at;
  if (v.state == RunState::kDone) v.progress.fraction = 1.0;
  if (run.bench_s) v.progress.bench_elapsed_s = v.progress.bench_total_s = *run.bench_s;
  if (run.bench_planned_s) v.progress.bench_planned_s = *run.bench_planned_s;
  if (run.outcome) api::ShowOutcome(*run.outcome, v);
  return v;
}

api::Status ValidateSessionDetails(const SessionDetails& d) {
  if (!api::IsIsoDate(d.date)) {
    return api::Status::InvalidArgument("date must be a calendar date YYYY-MM-DD", "date");
  }
  if (auto s = CheckCurrent(d.threshold_ma, "threshold_ma"); !s.ok()) return s;
  if (auto s = CheckCurrent(d.max_tolerated_ma, "max_tolerated_ma"); !s.ok()) return s;
  if (d.threshold_ma && d.max_tolerated_ma && *d.threshold_ma > *d.max_tolerated_ma) {
    return api::Status::InvalidArgument("max_tolerated_ma must not be below threshold_ma",
                                        "max_tolerated_ma");
  }
  return api::Status::Ok();
}

api::Result<Session> SessionRepository::Create(std::int64_t subject_id, std::int64_t leg_id,
                                               const SessionDetails& details) {
  if (auto s = ValidateSessionDetails(details); !s.ok()) return s;
  return db_.Write([&](Connection& c) -> api::Result<Session> {
    if (auto s =
            internal::RequireRow(c, "SELECT 1 FROM subjects WHERE id = ?1", subject_id, "subject");
        !s.ok()) {
      return s;
    }
    if (auto s = internal::RequireLegOfSubject(c, leg_id, subject_id); !s.ok()) return s;
    const api::UtcTime now = db_.Now();
    auto id = internal::InsertRow(
        c, "INSERT INTO sessions (subject_id, leg_id, created_at_utc) VALUES (?1, ?2, ?3)",
        subject_id, leg_id, api::FormatUtc(now));
    if (!id.ok()) return id.status();
    if (auto s = InsertRevision(c, *id, 1, details, std::nullopt, "", "", now); !s.ok()) return s;
    return GetSession(c, *id);
  });
}

api::Result<Session> SessionRepository::Get(std::int64_t session_id) {
  return db_.Read([&](Connection& c) { return GetSession(c, session_id); });
}

api::Result<std::vector<Session>> SessionRepository::ListForSubject(std::int64_t subject_id) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<Session>> {
    if (auto s =
            internal::RequireRow(c, "SELECT 1 FROM subjects WHERE id = ?1", subject_id, "subject");
        !s.ok()) {
      return s;
    }
    return QuerySessions(c, "WHERE s.subject_id = ?1", subject_id);
  });
}

api::Result<Session> SessionRepository::Correct(std::int64_t session_id,
                                                const SessionDetails& details,
                                                std::string_view reason,
                                                std::string_view recorded_by) {
  if (auto s = ValidateSessionDetails(details); !s.ok()) return s;
  if (reason.empty()) return api::Status::InvalidArgument("a correction needs a reason", "reason");
  return db_.Write([&](Connection& c) {
    return internal::AppendCorrection(
        c, session_id, GetSession, [&](int revision, std::int64_t corrects_id) {
          return InsertRevision(c, session_id, revision, details, corrects_id, reason, recorded_by,
                                db_.Now());
        });
  });
}

api::Result<std::vector<SessionRevision>> SessionRepository::Revisions(std::int64_t session_id) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<SessionRevision>> {
    if (auto s =
            internal::RequireRow(c, "SELECT 1 FROM sessions WHERE id = ?1", session_id, "session");
        !s.ok()) {
      return s;
    }
    return internal::QueryRows(
        c,
        "SELECT " + std::string(kRevisionColumns) +
            " FROM session_revisions r WHERE r.session_id = ?1"
            " ORDER BY r.revision",
        [](const Statement& s) { return ReadRevision(s, 0); }, session_id);
  });
}

api::Result<Run> SessionRepository::CreateRun(std::int64_t session_id, const NewRun& run) {
  if (run.protocol_name.empty()) {
    return api::Status::InvalidArgument("protocol_name must not be empty", "protocol_name");
  }
  if (run.protocol_version.empty()) {
    return api::Status::InvalidArgument("protocol_version must not be empty", "protocol_version");
  }
  if (!nlohmann::json::accept(run.parameters_json)) {
    return api::Status::InvalidArgument("parameters_json is not valid JSON", "parameters_json");
  }
  return db_.Write([&](Connection& c) -> api::Result<Run> {
    if (auto s =
            internal::RequireRow(c, "SELECT 1 FROM sessions WHERE id = ?1", session_id, "session");
        !s.ok()) {
      return s;
    }
    const api::UtcTime now = db_.Now();
    auto id = internal::InsertRow(
        c,
        "INSERT INTO runs (session_id, protocol_name, protocol_version, parameters_json,"
        " created_at_utc, bench_id) VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
        session_id, run.protocol_name, run.protocol_version, run.parameters_json, api::FormatUtc(now),
        db_.options().bench_id);
    if (!id.ok()) return id.status();
    if (auto s = AppendRunEvent(c, *id, RunState::kQueued, "", now); !s.ok()) return s;
    return GetRunIn(c, *id);
  });
}

api::Result<Run> SessionRepository::GetRun(std::int64_t run_id) {
  return db_.Read([&](Connection& c) { return GetRunIn(c, run_id); });
}

api::Result<std::vector<Run>> SessionRepository::ListRuns(std::int64_t session_id) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<Run>> {
    if (auto s =
            internal::RequireRow(c, "SELECT 1 FROM sessions WHERE id = ?1", session_id, "session");
        !s.ok()) {
      return s;
    }
    return QueryRuns(c, "WHERE r.session_id = ?1 ORDER BY r.id", session_id);
  });
}

api::Result<std::vector<Run>> SessionRepository::ListRunsPage(std::int64_t session_id,
                                                              std::int64_t after_id,
                                                              std::size_t limit) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<Run>> {
    if (auto s =
            internal::RequireRow(c, "SELECT 1 FROM sessions WHERE id = ?1", session_id, "session");
        !s.ok()) {
      return s;
    }
    return QueryRuns(c, "WHERE r.session_id = ?1 AND r.id > ?2 ORDER BY r.id LIMIT ?3", session_id,
                     after_id, static_cast<std::int64_t>(limit));
  });
}

api::Result<std::vector<Run>> SessionRepository::ListUnfinishedRuns() {
  return db_.Read([&](Connection& c) {
    return QueryRuns(c,
                     "WHERE r.bench_id IN (?1, '') AND (SELECT state FROM run_events"
                     " WHERE run_id = r.id ORDER BY id DESC LIMIT 1) IN ('queued', 'running')"
                     " ORDER BY r.id",
                     db_.options().bench_id);
  });
}

api::Result<Run> SessionRepository::RecordRunState(std::int64_t run_id, RunState state,
                                                   std::string_view message,
                                                   std::optional<RunBenchTime> bench,
                                                   const api::RunOutcome* outcome) {
  return db_.Write([&](Connection& c) -> api::Result<Run> {
    auto run = GetRunIn(c, run_id);
    if (!run.ok()) return run.status();
    if (!run->bench_id.empty() && run->bench_id != db_.options().bench_id) {
      return api::Status::FailedPrecondition("run " + std::to_string(run_id) +
                                             " belongs to bench '" + run->bench_id +
                                             "': only its own server moves it");
    }
    const RunState from = run->state;
    const bool allowed =
        (from == RunState::kQueued && (state == RunState::kRunning || state == RunState::kFailed ||
                                       state == RunState::kAborted)) ||
        (from == RunState::kRunning && api::IsFinal(state));
    if (!allowed) {
      return api::Status::FailedPrecondition("run " + std::to_string(run_id) + " cannot go from " +
                                             std::string(api::RunStateName(from)) + " to " +
                                             std::string(api::RunStateName(state)));
    }
    if (bench && (!api::IsFinal(state) || !(bench->ran_s >= 0.0) || !(bench->planned_s >= 0.0) ||
                  !std::isfinite(bench->ran_s) || !std::isfinite(bench->planned_s))) {
      return api::Status::InvalidArgument("a bench time belongs to a run that ended, >= 0 s",
                                          "bench");
    }
    if (outcome != nullptr && (outcome->state != state || !api::IsFinal(state))) {
      return api::Status::InvalidArgument("an outcome belongs to the run's terminal state",
                                          "outcome");
    }
    if (auto s = AppendRunEvent(c, run_id, state, message, db_.Now(), bench, outcome); !s.ok()) {
      return s;
    }
    return GetRunIn(c, run_id);
  });
}

}  // namespace fesbench::storage
