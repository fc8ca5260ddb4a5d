#include "storage/sessions.h"

#include <cmath>
#include <functional>
#include <nlohmann/json.hpp>

#include "storage/row_helpers.h"

namespace fesbench::storage {
namespace {

constexpr std::string_view kRevisionColumns =
    "r.id, r.revision, r.session_date, r.accelerometer_placement, r.threshold_ma,"
    " r.max_tolerated_ma, r.notes, r.corrects_id, r.reason, r.recorded_at_utc";

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
  const auto recorded = ParseUtc(s.Text(first + 9));
  if (!recorded) return internal::BadStoredValue("session revision");
  revision.recorded_at = *recorded;
  return revision;
}

api::Result<std::vector<Session>> QuerySessions(Connection& c, std::string_view where,
                                                const std::function<void(Statement&)>& bind) {
  const std::string sql =
      "SELECT s.id, s.subject_id, s.leg_id, s.created_at_utc, " + std::string(kRevisionColumns) +
      " FROM sessions s JOIN session_revisions r ON r.session_id = s.id"
      " AND r.revision = (SELECT MAX(revision) FROM session_revisions WHERE session_id = s.id) " +
      std::string(where) + " ORDER BY s.id";
  auto statement = c.Prepare(sql);
  if (!statement.ok()) return statement.status();
  bind(*statement);
  std::vector<Session> sessions;
  while (true) {
    auto row = statement->Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    Session session;
    session.id = statement->Int64(0);
    session.subject_id = statement->Int64(1);
    session.leg_id = statement->Int64(2);
    const auto created = ParseUtc(statement->Text(3));
    auto revision = ReadRevision(*statement, 4);
    if (!created) return internal::BadStoredValue("session");
    if (!revision.ok()) return revision.status();
    session.created_at = *created;
    session.current = std::move(*revision);
    sessions.push_back(std::move(session));
  }
  return sessions;
}

api::Result<Session> GetSession(Connection& c, std::int64_t id) {
  auto sessions = QuerySessions(c, "WHERE s.id = ?1", [&](Statement& s) { s.Bind(1, id); });
  if (!sessions.ok()) return sessions.status();
  if (sessions->empty())
    return api::Status::NotFound("session " + std::to_string(id) + " not found");
  return std::move(sessions->front());
}

api::Status InsertRevision(Connection& c, std::int64_t session_id, int revision,
                           const SessionDetails& d, std::optional<std::int64_t> corrects_id,
                           std::string_view reason, UtcTime now) {
  auto insert = c.Prepare(
      "INSERT INTO session_revisions (session_id, revision, session_date,"
      " accelerometer_placement, threshold_ma, max_tolerated_ma, notes, corrects_id, reason,"
      " recorded_at_utc) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)");
  if (!insert.ok()) return insert.status();
  insert->Bind(1, session_id)
      .Bind(2, revision)
      .Bind(3, d.date)
      .Bind(4, d.accelerometer_placement)
      .Bind(5, d.threshold_ma)
      .Bind(6, d.max_tolerated_ma)
      .Bind(7, d.notes)
      .Bind(8, corrects_id)
      .Bind(9, reason)
      .Bind(10, FormatUtc(now));
  return insert->Run();
}

api::Status CheckCurrent(const std::optional<double>& value, const char* field) {
  if (value && (!std::isfinite(*value) || *value < 0 || *value > 100)) {
    return api::Status::InvalidArgument(std::string(field) + " must be in [0, 100] mA", field);
  }
  return api::Status::Ok();
}

constexpr std::string_view kRunSql =
    "SELECT r.id, r.session_id, r.protocol_name, r.protocol_version, r.parameters_json,"
    " r.created_at_utc,"
    " (SELECT state FROM run_events WHERE run_id = r.id ORDER BY id DESC LIMIT 1),"
    " (SELECT message FROM run_events WHERE run_id = r.id ORDER BY id DESC LIMIT 1),"
    " (SELECT MIN(at_utc) FROM run_events WHERE run_id = r.id AND state = 'running'),"
    " (SELECT MAX(at_utc) FROM run_events WHERE run_id = r.id"
    "    AND state IN ('completed', 'failed', 'cancelled'))"
    " FROM runs r ";

api::Result<std::vector<Run>> QueryRuns(Connection& c, std::string_view where, std::int64_t id) {
  auto statement = c.Prepare(std::string(kRunSql) + std::string(where) + " ORDER BY r.id");
  if (!statement.ok()) return statement.status();
  statement->Bind(1, id);
  std::vector<Run> runs;
  while (true) {
    auto row = statement->Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    Run run;
    run.id = statement->Int64(0);
    run.session_id = statement->Int64(1);
    run.protocol_name = statement->Text(2);
    run.protocol_version = statement->Text(3);
    run.parameters_json = statement->Text(4);
    const auto created = ParseUtc(statement->Text(5));
    const auto state = ParseRunState(statement->Text(6));
    if (!created || !state) return internal::BadStoredValue("run");
    run.created_at = *created;
    run.state = *state;
    run.message = statement->Text(7);
    if (!statement->IsNull(8)) run.started_at = ParseUtc(statement->Text(8));
    if (!statement->IsNull(9)) run.finished_at = ParseUtc(statement->Text(9));
    runs.push_back(std::move(run));
  }
  return runs;
}

api::Result<Run> GetRunIn(Connection& c, std::int64_t id) {
  auto runs = QueryRuns(c, "WHERE r.id = ?1", id);
  if (!runs.ok()) return runs.status();
  if (runs->empty()) return api::Status::NotFound("run " + std::to_string(id) + " not found");
  return std::move(runs->front());
}

api::Status AppendRunEvent(Connection& c, std::int64_t run_id, RunState state,
                           std::string_view message, UtcTime now) {
  auto insert =
      c.Prepare("INSERT INTO run_events (run_id, state, message, at_utc) VALUES (?1, ?2, ?3, ?4)");
  if (!insert.ok()) return insert.status();
  insert->Bind(1, run_id).Bind(2, RunStateName(state)).Bind(3, message).Bind(4, FormatUtc(now));
  return insert->Run();
}

}  // namespace

std::string_view RunStateName(RunState state) {
  switch (state) {
    case RunState::kQueued:
      return "queued";
    case RunState::kRunning:
      return "running";
    case RunState::kCompleted:
      return "completed";
    case RunState::kFailed:
      return "failed";
    case RunState::kCancelled:
      return "cancelled";
  }
  return "failed";
}

std::optional<RunState> ParseRunState(std::string_view name) {
  for (RunState state : {RunState::kQueued, RunState::kRunning, RunState::kCompleted,
                         RunState::kFailed, RunState::kCancelled}) {
    if (RunStateName(state) == name) return state;
  }
  return std::nullopt;
}

bool IsTerminal(RunState state) {
  return state == RunState::kCompleted || state == RunState::kFailed ||
         state == RunState::kCancelled;
}

api::Status ValidateSessionDetails(const SessionDetails& d) {
  if (!IsIsoDate(d.date)) {
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
    auto leg = c.Prepare("SELECT subject_id FROM legs WHERE id = ?1");
    if (!leg.ok()) return leg.status();
    leg->Bind(1, leg_id);
    auto found = leg->Step();
    if (!found.ok()) return found.status();
    if (!*found) return api::Status::NotFound("leg " + std::to_string(leg_id) + " not found");
    if (leg->Int64(0) != subject_id) {
      return api::Status::InvalidArgument(
          "leg " + std::to_string(leg_id) + " belongs to another subject", "leg_id");
    }
    const UtcTime now = db_.Now();
    auto insert =
        c.Prepare("INSERT INTO sessions (subject_id, leg_id, created_at_utc) VALUES (?1, ?2, ?3)");
    if (!insert.ok()) return insert.status();
    insert->Bind(1, subject_id).Bind(2, leg_id).Bind(3, FormatUtc(now));
    if (auto s = insert->Run(); !s.ok()) return s;
    const std::int64_t id = c.LastInsertRowId();
    if (auto s = InsertRevision(c, id, 1, details, std::nullopt, "", now); !s.ok()) return s;
    return GetSession(c, id);
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
    return QuerySessions(c, "WHERE s.subject_id = ?1",
                         [&](Statement& s) { s.Bind(1, subject_id); });
  });
}

api::Result<Session> SessionRepository::Correct(std::int64_t session_id,
                                                const SessionDetails& details,
                                                std::string_view reason) {
  if (auto s = ValidateSessionDetails(details); !s.ok()) return s;
  if (reason.empty()) return api::Status::InvalidArgument("a correction needs a reason", "reason");
  return db_.Write([&](Connection& c) -> api::Result<Session> {
    auto session = GetSession(c, session_id);
    if (!session.ok()) return session.status();
    if (auto s = InsertRevision(c, session_id, session->current.revision + 1, details,
                                session->current.id, reason, db_.Now());
        !s.ok()) {
      return s;
    }
    return GetSession(c, session_id);
  });
}

api::Result<std::vector<SessionRevision>> SessionRepository::Revisions(std::int64_t session_id) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<SessionRevision>> {
    if (auto s =
            internal::RequireRow(c, "SELECT 1 FROM sessions WHERE id = ?1", session_id, "session");
        !s.ok()) {
      return s;
    }
    auto statement = c.Prepare("SELECT " + std::string(kRevisionColumns) +
                               " FROM session_revisions r WHERE r.session_id = ?1"
                               " ORDER BY r.revision");
    if (!statement.ok()) return statement.status();
    statement->Bind(1, session_id);
    std::vector<SessionRevision> revisions;
    while (true) {
      auto row = statement->Step();
      if (!row.ok()) return row.status();
      if (!*row) break;
      auto revision = ReadRevision(*statement, 0);
      if (!revision.ok()) return revision.status();
      revisions.push_back(std::move(*revision));
    }
    return revisions;
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
    const UtcTime now = db_.Now();
    auto insert = c.Prepare(
        "INSERT INTO runs (session_id, protocol_name, protocol_version, parameters_json,"
        " created_at_utc) VALUES (?1, ?2, ?3, ?4, ?5)");
    if (!insert.ok()) return insert.status();
    insert->Bind(1, session_id)
        .Bind(2, run.protocol_name)
        .Bind(3, run.protocol_version)
        .Bind(4, run.parameters_json)
        .Bind(5, FormatUtc(now));
    if (auto s = insert->Run(); !s.ok()) return s;
    const std::int64_t id = c.LastInsertRowId();
    if (auto s = AppendRunEvent(c, id, RunState::kQueued, "", now); !s.ok()) return s;
    return GetRunIn(c, id);
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
    return QueryRuns(c, "WHERE r.session_id = ?1", session_id);
  });
}

api::Result<Run> SessionRepository::RecordRunState(std::int64_t run_id, RunState state,
                                                   std::string_view message) {
  return db_.Write([&](Connection& c) -> api::Result<Run> {
    auto run = GetRunIn(c, run_id);
    if (!run.ok()) return run.status();
    const RunState from = run->state;
    const bool allowed =
        (from == RunState::kQueued && (state == RunState::kRunning || state == RunState::kFailed ||
                                       state == RunState::kCancelled)) ||
        (from == RunState::kRunning && IsTerminal(state));
    if (!allowed) {
      return api::Status::FailedPrecondition("run " + std::to_string(run_id) + " cannot go from " +
                                             std::string(RunStateName(from)) + " to " +
                                             std::string(RunStateName(state)));
    }
    if (auto s = AppendRunEvent(c, run_id, state, message, db_.Now()); !s.ok()) return s;
    return GetRunIn(c, run_id);
  });
}

}  // namespace fesbench::storage
