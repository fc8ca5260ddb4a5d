#pragma once

/// @file
/// Sessions (one visit of a subject at the bench, for one leg) and runs (one
/// execution of a protocol within a session), docs/ARCHITECTURE.md. Session details
/// are revisions (a correction points at what it corrects); a run's state is
/// the last of its append-only state events.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/run.h"
#include "api/run_state.h"
#include "api/session.h"
#include "api/status.h"
#include "storage/database.h"

namespace fesbench::storage {

// The details are the wire's (api/session.h).
using api::SessionDetails;

struct SessionRevision {
  std::int64_t id = 0;
  int revision = 1;
  SessionDetails details;
  std::optional<std::int64_t> corrects_id;
  std::string reason;
  api::UtcTime recorded_at;
  std::string recorded_by;  ///< user name of who recorded it ("" if unknown).
};

struct Session {
  std::int64_t id = 0;
  std::int64_t subject_id = 0;
  std::int64_t leg_id = 0;
  api::UtcTime created_at;
  SessionRevision current;  ///< the latest revision.
};

/// The run states are the one vocabulary of api/run_state.h; run_events
/// stores their names.
using api::RunState;

struct NewRun {
  std::string protocol_name;           ///< e.g. "irc_ramp".
  std::string protocol_version;        ///< e.g. "1.0".
  std::string parameters_json = "{}";  ///< the protocol's parameters, valid JSON.
};

struct Run {
  std::int64_t id = 0;
  std::int64_t session_id = 0;
  std::string protocol_name;
  std::string protocol_version;
  std::string parameters_json;
  std::string bench_id;  ///< the bench that ran it ('' before benches had ids).
  RunState state = RunState::kQueued;
  std::string message;  ///< of the last state event.
  api::UtcTime created_at;
  std::optional<api::UtcTime> started_at;   ///< first "running" event.
  std::optional<api::UtcTime> finished_at;  ///< the terminal event.
  /// Bench time, s, as the run ran and as planned (on its terminal event;
  /// unset for runs stored before schema 18 and runs closed at a restart).
  std::optional<double> bench_s, bench_planned_s;
  /// What the run concluded, stored with its terminal event (schema 19;
  /// runs that ended before have the one migration 19 derived).
  std::optional<api::RunOutcome> outcome;
};

/// A finished run's bench time, s: as it ran (however it ended) and as planned.
struct RunBenchTime {
  double ran_s = 0.0;
  double planned_s = 0.0;
};

/// Checks SessionDetails (field names the member): a valid date, currents in
/// [0, 100] mA, threshold ≤ max tolerated.
api::Status ValidateSessionDetails(const SessionDetails& details);

/// The run resource (api/run.h) of a stored run: everything but its trials,
/// its outcome shown by api::ShowOutcome. A done run's progress is 1; the
/// reason is kept for failed and aborted runs; a stored protocol version
/// that is not a number reads as 0 and parameters that are not numbers are
/// left out.
api::RunView RunViewOf(const Run& run);

class SessionRepository {
 public:
  explicit SessionRepository(Database& db) : db_(db) {}

  /// Errors: kNotFound for an unknown subject or leg; kInvalidArgument
  /// (field "leg_id") for a leg of another subject, or bad details.
  api::Result<Session> Create(std::int64_t subject_id, std::int64_t leg_id,
                              const SessionDetails& details);
  api::Result<Session> Get(std::int64_t session_id);
  /// The subject's sessions, oldest first (kNotFound for an unknown subject).
  api::Result<std::vector<Session>> ListForSubject(std::int64_t subject_id);
  /// Adds a revision pointing at the current one; `reason` must not be empty.
  api::Result<Session> Correct(std::int64_t session_id, const SessionDetails& details,
                               std::string_view reason, std::string_view recorded_by = {});
  api::Result<std::vector<SessionRevision>> Revisions(std::int64_t session_id);

  /// A new run in state queued, on this database's bench. kNotFound for an unknown session;
  /// kInvalidArgument for empty names or invalid parameters JSON.
  api::Result<Run> CreateRun(std::int64_t session_id, const NewRun& run);
  api::Result<Run> GetRun(std::int64_t run_id);
  api::Result<std::vector<Run>> ListRuns(std::int64_t session_id);
  /// At most `limit` of the session's runs with id > `after_id`, ascending
  /// (keyset paging on index runs_session).
  api::Result<std::vector<Run>> ListRunsPage(std::int64_t session_id, std::int64_t after_id,
                                             std::size_t limit);
  /// Every run of this bench (DatabaseOptions::bench_id, or '') whose last
  /// state is queued or running, oldest first (at a start: the runs a
  /// stopped process left unfinished; another bench's are its own).
  api::Result<std::vector<Run>> ListUnfinishedRuns();
  /// Appends a state event. Allowed: queued → running | failed | aborted;
  /// running → done | failed | aborted. Anything else (including from
  /// a terminal state) is kFailedPrecondition naming both states, and so is
  /// a run of another bench (only its own server moves it).
  /// `bench`: the bench time of a run that ended (terminal states only).
  /// `outcome`: what a run that ended concluded (terminal states only; its
  /// state must be `state`), written once with the terminal event.
  api::Result<Run> RecordRunState(std::int64_t run_id, RunState state,
                                  std::string_view message = {},
                                  std::optional<RunBenchTime> bench = std::nullopt,
                                  const api::RunOutcome* outcome = nullptr);

 private:
  Database& db_;
};

}  // namespace fesbench::storage
