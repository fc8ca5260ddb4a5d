#include "storage/migrations.h"

#include <algorithm>
#include <initializer_list>

#include "api/trial_kind.h"

namespace fesbench::storage {
namespace {

// Triggers that make each table append-only: nothing is ever silently
// overwritten; a correction is a new row that points at what it corrects.
std::string AppendOnlyUpdate(const std::string& t) {
  return "CREATE TRIGGER " + t + "_no_update BEFORE UPDATE ON " + t +
         " BEGIN SELECT RAISE(ABORT, '" + t +
         " is append-only: add a correcting row instead'); END;\n";
}

std::string AppendOnly(std::initializer_list<const char*> tables) {
  std::string sql;
  for (const char* table : tables) {
    const std::string t(table);
    sql += AppendOnlyUpdate(t);
    sql += "CREATE TRIGGER " + t + "_no_delete BEFORE DELETE ON " + t +
           " BEGIN SELECT RAISE(ABORT, '" + t + " is append-only: rows are never deleted'); END;\n";
  }
  return sql;
}

// Conventions for every migration:
//  * *_utc columns hold ISO 8601 UTC text "YYYY-MM-DDTHH:MM:SS.ffffffZ"
//    (fixed width: text order is time order).
//  * Column names carry their unit (height_cm, threshold_ma, sample_rate_hz).
//  * A corrected row is never updated: the correction is a new row whose
//    corrects_id points at the row it replaces (a partial unique index keeps
//    the chain linear), and the current value is the row nobody corrects.

const char* const kMigration1 = R"sql(
CREATE TABLE schema_migrations (
  version        INTEGER PRIMARY KEY,
  name           TEXT NOT NULL,
  applied_at_utc TEXT NOT NULL
);

-- Subjects are known by a pseudonymous code only; anthropometrics live in
-- revisions so a correction never overwrites what was recorded.
CREATE TABLE subjects (
  id             INTEGER PRIMARY KEY,
  code           TEXT NOT NULL UNIQUE CHECK (length(code) BETWEEN 1 AND 32),
  created_at_utc TEXT NOT NULL
);
CREATE TABLE subject_revisions (
  id                    INTEGER PRIMARY KEY,
  subject_id            INTEGER NOT NULL REFERENCES subjects(id),
  revision              INTEGER NOT NULL CHECK (revision >= 1),
  age_years             INTEGER CHECK (age_years BETWEEN 0 AND 130),
  sex                   TEXT NOT NULL CHECK (sex IN ('female', 'male', 'other', 'undisclosed')),
  height_cm             REAL CHECK (height_cm > 0),
  weight_kg             REAL CHECK (weight_kg > 0),
  shank_length_cm       REAL CHECK (shank_length_cm > 0),
  calf_circumference_cm REAL CHECK (calf_circumference_cm > 0),
  corrects_id           INTEGER REFERENCES subject_revisions(id),
  reason                TEXT NOT NULL DEFAULT '',
  recorded_at_utc       TEXT NOT NULL,
  UNIQUE (subject_id, revision),
  CHECK ((revision = 1) = (corrects_id IS NULL))
);
CREATE UNIQUE INDEX subject_revisions_corrects ON subject_revisions(corrects_id)
  WHERE corrects_id IS NOT NULL;

CREATE TABLE legs (
  id             INTEGER PRIMARY KEY,
  subject_id     INTEGER NOT NULL REFERENCES subjects(id),
  side           TEXT NOT NULL CHECK (side IN ('left', 'right')),
  created_at_utc TEXT NOT NULL,
  UNIQUE (subject_id, side),
  UNIQUE (id, subject_id)
);

CREATE TABLE sessions (
  id             INTEGER PRIMARY KEY,
  subject_id     INTEGER NOT NULL REFERENCES subjects(id),
  leg_id         INTEGER NOT NULL,
  created_at_utc TEXT NOT NULL,
  FOREIGN KEY (leg_id, subject_id) REFERENCES legs(id, subject_id)
);
CREATE INDEX sessions_subject ON sessions(subject_id, id);
CREATE TABLE session_revisions (
  id                      INTEGER PRIMARY KEY,
  session_id              INTEGER NOT NULL REFERENCES sessions(id),
  revision                INTEGER NOT NULL CHECK (revision >= 1),
  session_date            TEXT NOT NULL
                          CHECK (session_date GLOB '[0-9][0-9][0-9][0-9]-[0-1][0-9]-[0-3][0-9]'),
  accelerometer_placement TEXT NOT NULL,
  threshold_ma            REAL CHECK (threshold_ma BETWEEN 0 AND 100),
  max_tolerated_ma        REAL CHECK (max_tolerated_ma BETWEEN 0 AND 100),
  notes                   TEXT NOT NULL DEFAULT '',
  corrects_id             INTEGER REFERENCES session_revisions(id),
  reason                  TEXT NOT NULL DEFAULT '',
  recorded_at_utc         TEXT NOT NULL,
  UNIQUE (session_id, revision),
  CHECK ((revision = 1) = (corrects_id IS NULL)),
  CHECK (threshold_ma IS NULL OR max_tolerated_ma IS NULL OR threshold_ma <= max_tolerated_ma)
);
CREATE UNIQUE INDEX session_revisions_corrects ON session_revisions(corrects_id)
  WHERE corrects_id IS NOT NULL;

-- A run is one execution of a protocol; its state is the last of its events.
CREATE TABLE runs (
  id               INTEGER PRIMARY KEY,
  session_id       INTEGER NOT NULL REFERENCES sessions(id),
  protocol_name    TEXT NOT NULL CHECK (length(protocol_name) > 0),
  protocol_version TEXT NOT NULL CHECK (length(protocol_version) > 0),
  parameters_json  TEXT NOT NULL CHECK (json_valid(parameters_json)),
  created_at_utc   TEXT NOT NULL
);
CREATE INDEX runs_session ON runs(session_id, id);
CREATE TABLE run_events (
  id      INTEGER PRIMARY KEY,
  run_id  INTEGER NOT NULL REFERENCES runs(id),
  state   TEXT NOT NULL
          CHECK (state IN ('queued', 'running', 'completed', 'failed', 'cancelled')),
  message TEXT NOT NULL DEFAULT '',
  at_utc  TEXT NOT NULL
);
CREATE INDEX run_events_run ON run_events(run_id, id);

CREATE TABLE users (
  id             INTEGER PRIMARY KEY,
  name           TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 64),
  role           TEXT NOT NULL CHECK (role IN ('clinician', 'analyst', 'admin')),
  created_at_utc TEXT NOT NULL
);
CREATE TABLE user_deactivations (
  user_id INTEGER PRIMARY KEY REFERENCES users(id),
  reason  TEXT NOT NULL DEFAULT '',
  at_utc  TEXT NOT NULL
);
-- Tokens are stored as SHA-256 digests only; the plain token is shown once.
CREATE TABLE tokens (
  id             INTEGER PRIMARY KEY,
  user_id        INTEGER NOT NULL REFERENCES users(id),
  token_sha256   BLOB NOT NULL UNIQUE CHECK (length(token_sha256) = 32),
  label          TEXT NOT NULL DEFAULT '',
  created_at_utc TEXT NOT NULL,
  expires_at_utc TEXT
);
CREATE TABLE token_revocations (
  token_id INTEGER PRIMARY KEY REFERENCES tokens(id),
  at_utc   TEXT NOT NULL
);

CREATE TABLE audit_log (
  id              INTEGER PRIMARY KEY,
  at_utc          TEXT NOT NULL,
  user_id         INTEGER REFERENCES users(id),
  actor           TEXT NOT NULL,
  action          TEXT NOT NULL CHECK (length(action) > 0),
  target          TEXT NOT NULL DEFAULT '',
  request_summary TEXT NOT NULL DEFAULT '',
  outcome         TEXT NOT NULL DEFAULT ''
);
CREATE INDEX audit_log_time ON audit_log(at_utc);
)sql";

// Samples are BLOBs of little-endian IEEE-754 float64, 8 bytes per sample,
// one BLOB per channel; `grp` is 'main' (with the t_s time base) or 'emg'
// (its own rate and t_s), as in api::Trial.
const char* const kMigration2 = R"sql(
CREATE TABLE trials (
  id                 INTEGER PRIMARY KEY,
  session_id         INTEGER NOT NULL REFERENCES sessions(id),
  run_id             INTEGER REFERENCES runs(id),
  name               TEXT,
  start_time_unix_ms INTEGER,
  created_at_utc     TEXT NOT NULL
);
CREATE INDEX trials_session ON trials(session_id, id);
CREATE INDEX trials_run ON trials(run_id) WHERE run_id IS NOT NULL;
CREATE TABLE trial_channels (
  id             INTEGER PRIMARY KEY,
  trial_id       INTEGER NOT NULL REFERENCES trials(id),
  grp            TEXT NOT NULL CHECK (grp IN ('main', 'emg')),
  ordinal        INTEGER NOT NULL CHECK (ordinal >= 0),
  name           TEXT NOT NULL,
  unit           TEXT NOT NULL,
  sample_rate_hz REAL NOT NULL CHECK (sample_rate_hz > 0),
  sample_count   INTEGER NOT NULL CHECK (sample_count >= 0),
  samples_f64le  BLOB NOT NULL CHECK (length(samples_f64le) = 8 * sample_count),
  UNIQUE (trial_id, grp, ordinal),
  UNIQUE (trial_id, grp, name)
);
)sql";

// Parameter sets: the JSON text (api/parameter_set_json.h) plus indexed
// columns, so a subject's history is an index range scan.
const char* const kMigration3 = R"sql(
CREATE TABLE parameter_sets (
  id               INTEGER PRIMARY KEY,
  subject_id       INTEGER NOT NULL REFERENCES subjects(id),
  leg_id           INTEGER NOT NULL,
  version          INTEGER NOT NULL CHECK (version >= 1),
  model            TEXT NOT NULL,
  irc_method       TEXT NOT NULL DEFAULT '',
  passive_method   TEXT NOT NULL DEFAULT '',
  active_method    TEXT NOT NULL DEFAULT '',
  software_version TEXT NOT NULL DEFAULT '',
  supersedes_id    INTEGER REFERENCES parameter_sets(id),
  created_at_utc   TEXT NOT NULL,
  params_json      TEXT NOT NULL CHECK (json_valid(params_json)),
  FOREIGN KEY (leg_id, subject_id) REFERENCES legs(id, subject_id),
  UNIQUE (subject_id, leg_id, version)
);
CREATE INDEX parameter_sets_subject_time ON parameter_sets(subject_id, created_at_utc);
CREATE INDEX parameter_sets_leg_time ON parameter_sets(subject_id, leg_id, created_at_utc);
CREATE TABLE parameter_set_trials (
  parameter_set_id INTEGER NOT NULL REFERENCES parameter_sets(id),
  trial_id         INTEGER NOT NULL REFERENCES trials(id),
  PRIMARY KEY (parameter_set_id, trial_id)
) WITHOUT ROWID;
CREATE INDEX parameter_set_trials_trial ON parameter_set_trials(trial_id);
)sql";

const char* const kMigration4 = R"sql(
CREATE TABLE predictions (
  id               INTEGER PRIMARY KEY,
  parameter_set_id INTEGER NOT NULL REFERENCES parameter_sets(id),
  trial_id         INTEGER REFERENCES trials(id),
  input_json       TEXT NOT NULL CHECK (json_valid(input_json)),
  output_json      TEXT NOT NULL CHECK (json_valid(output_json)),
  created_at_utc   TEXT NOT NULL
);
CREATE INDEX predictions_parameter_set ON predictions(parameter_set_id, id);
CREATE TABLE evaluations (
  id               INTEGER PRIMARY KEY,
  parameter_set_id INTEGER NOT NULL REFERENCES parameter_sets(id),
  trial_id         INTEGER NOT NULL REFERENCES trials(id),
  prediction_id    INTEGER REFERENCES predictions(id),
  channel          TEXT NOT NULL,
  unit             TEXT NOT NULL,
  rms_error        REAL NOT NULL CHECK (rms_error >= 0),
  max_abs_error    REAL NOT NULL CHECK (max_abs_error >= 0),
  details_json     TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(details_json)),
  created_at_utc   TEXT NOT NULL
);
CREATE INDEX evaluations_parameter_set ON evaluations(parameter_set_id, id);
CREATE INDEX evaluations_trial ON evaluations(trial_id, id);
)sql";

// Who recorded each revision (the user name; '' for rows from before this
// migration and for revisions written by the server itself without a user).
const char* const kMigration5 = R"sql(
ALTER TABLE subject_revisions ADD COLUMN recorded_by TEXT NOT NULL DEFAULT '';
ALTER TABLE session_revisions ADD COLUMN recorded_by TEXT NOT NULL DEFAULT '';
)sql";

// One run vocabulary (docs/PROTOCOLS.md, "Runs"): run_events used
// 'completed' and 'cancelled' for done and aborted. The table is rebuilt
// with the new names (the append-only triggers are recreated with it).
const char* const kMigration6 = R"sql(
CREATE TABLE run_events_v6 (
  id      INTEGER PRIMARY KEY,
  run_id  INTEGER NOT NULL REFERENCES runs(id),
  state   TEXT NOT NULL
          CHECK (state IN ('queued', 'running', 'done', 'failed', 'aborted')),
  message TEXT NOT NULL DEFAULT '',
  at_utc  TEXT NOT NULL
);
INSERT INTO run_events_v6 (id, run_id, state, message, at_utc)
  SELECT id, run_id,
         CASE state WHEN 'completed' THEN 'done' WHEN 'cancelled' THEN 'aborted' ELSE state END,
         message, at_utc
  FROM run_events ORDER BY id;
DROP TRIGGER run_events_no_update;
DROP TRIGGER run_events_no_delete;
DROP TABLE run_events;
ALTER TABLE run_events_v6 RENAME TO run_events;
CREATE INDEX run_events_run ON run_events(run_id, id);
)sql";

// The e-stop latch outlives the process (docs/SAFETY.md): each press and each
// clearing is a row; the latch is set when the last row says so. A restart
// re-latches it until a person clears it.
const char* const kMigration7 = R"sql(
CREATE TABLE estop_events (
  id          INTEGER PRIMARY KEY,
  latched     INTEGER NOT NULL CHECK (latched IN (0, 1)),
  source      TEXT NOT NULL DEFAULT '',
  recorded_by TEXT NOT NULL DEFAULT '',
  at_utc      TEXT NOT NULL
);
)sql";

// The pulses a stimulator delivered during a trial (docs/MODEL.md, api::PulseRecord),
// as read back: one row per trial that has them, times and amplitudes as
// little-endian float64 BLOBs like trial_channels. (Number 8: 7 is taken by
// a change developed beside this one.)
const char* const kMigration8 = R"sql(
CREATE TABLE trial_pulses (
  trial_id        INTEGER PRIMARY KEY REFERENCES trials(id),
  pulse_rate_hz   REAL NOT NULL CHECK (pulse_rate_hz > 0),
  pulse_width_us  REAL NOT NULL CHECK (pulse_width_us > 0),
  pulse_count     INTEGER NOT NULL CHECK (pulse_count >= 0),
  t_s_f64le       BLOB NOT NULL CHECK (length(t_s_f64le) = 8 * pulse_count),
  stim_ma_f64le   BLOB NOT NULL CHECK (length(stim_ma_f64le) = 8 * pulse_count)
);
)sql";

// Keyset paging of the parameter-set list filtered by subject (and leg):
// the rows of one subject in id order, so a deep page is a range seek.
const char* const kMigration9 = R"sql(
CREATE INDEX parameter_sets_subject_id ON parameter_sets(subject_id, id);
CREATE INDEX parameter_sets_leg_id ON parameter_sets(subject_id, leg_id, id);
)sql";

// Keyset paging of the audit log filtered by user, newest first: one
// user's rows in id order, so a deep page is a range seek.
const char* const kMigration10 = R"sql(
CREATE INDEX audit_log_user_id ON audit_log(user_id, id);
)sql";

// Where an imported trial came from (storage/trials.h TrialImport).
const char* const kMigration11 = R"sql(
CREATE TABLE trial_imports (
  trial_id          INTEGER PRIMARY KEY REFERENCES trials(id),
  format            TEXT NOT NULL,
  source            TEXT NOT NULL DEFAULT '',
  spec_json         TEXT NOT NULL DEFAULT '{}',
  imported_by       TEXT NOT NULL DEFAULT '',
  original_trial_id INTEGER
);
)sql";

// Several benches on one database: every run and every e-stop
// press belongs to the bench whose server made it. Rows from before are
// the bench '' (one server had the file), which any server adopts.
const char* const kMigration12 = R"sql(
ALTER TABLE runs ADD COLUMN bench_id TEXT NOT NULL DEFAULT '';
CREATE INDEX runs_bench ON runs(bench_id, id);
ALTER TABLE estop_events ADD COLUMN bench_id TEXT NOT NULL DEFAULT '';
CREATE INDEX estop_events_bench ON estop_events(bench_id, id);
)sql";

// A parameter set names the run that identified it: a run's set
// is an index lookup, not a search of the leg's history. Sets stored before
// have none (append-only: they are not rewritten).
const char* const kMigration13 = R"sql(
ALTER TABLE parameter_sets ADD COLUMN run_id BIGINT REFERENCES runs(id);
CREATE INDEX parameter_sets_run ON parameter_sets(run_id) WHERE run_id IS NOT NULL;
)sql";

// Every trial names its kind (api/trial_kind.h): identification,
// prediction and the clients read the column instead of decoding names.
// Trials stored before get the kind their name belongs to (exact names
// first, then the longest family stem followed by "_" and a suffix, as
// api::FindTrialKind, without checking the suffix's characters); a name of
// no kind stays NULL. trials is append-only, so this one back-fill lifts the
// trigger for its UPDATE: `lift` and `restore` are each engine's DDL.
std::string TrialKindMigration(const std::string& lift, const std::string& restore) {
  std::string cases;
  std::vector<const api::TrialKindInfo*> families;
  for (const api::TrialKindInfo& k : api::TrialKinds()) {
    cases += "  WHEN name = '" + std::string(k.name) + "' THEN '" + std::string(k.name) + "'\n";
    if (k.family) families.push_back(&k);
  }
  std::stable_sort(families.begin(), families.end(),
                   [](const auto* a, const auto* b) { return a->name.size() > b->name.size(); });
  for (const api::TrialKindInfo* k : families) {
    const std::string stem = std::string(k->name) + "_";
    cases += "  WHEN substr(name, 1, " + std::to_string(stem.size()) + ") = '" + stem +
             "' AND length(name) > " + std::to_string(stem.size()) + " THEN '" +
             std::string(k->name) + "'\n";
  }
  return "ALTER TABLE trials ADD COLUMN kind TEXT;\n" + lift +
         "UPDATE trials SET kind = CASE\n" + cases + "  END;\n" + restore;
}

// A clinician's approval of a parameter set for its leg (docs/SAFETY.md,
// which set gates stimulation): the leg's approved set is the one of its
// newest approval, and an approval is never withdrawn, only followed by
// another. leg_id repeats the set's leg (the repository copies it from the
// set in the approving transaction) for the leg's newest approval to be one
// index probe. Sets a bench run stored before approvals existed are that
// run's own measurement, approved by it, in the order they were stored;
// every other set stays a candidate until a clinician approves it.
// `id_type`, `int_type` and `utc_type` are each engine's.
std::string ApprovalMigration(const std::string& id_type, const std::string& int_type,
                              const std::string& utc_type) {
  return "CREATE TABLE parameter_set_approvals (\n"
         "  id                  " + id_type + ",\n"
         "  parameter_set_id    " + int_type + " NOT NULL REFERENCES parameter_sets(id),\n"
         "  leg_id              " + int_type + " NOT NULL REFERENCES legs(id),\n"
         "  approved_by_user_id " + int_type + " REFERENCES users(id),\n"
         "  approved_by         TEXT NOT NULL CHECK (length(approved_by) > 0),\n"
         "  run_id              " + int_type + " REFERENCES runs(id),\n"
         "  note                TEXT NOT NULL CHECK (length(note) BETWEEN 1 AND 500),\n"
         "  approved_at_utc     " + utc_type + " NOT NULL\n"
         ");\n"
         "CREATE INDEX parameter_set_approvals_leg ON parameter_set_approvals(leg_id, id);\n"
         "CREATE INDEX parameter_set_approvals_set ON parameter_set_approvals(parameter_set_id, "
         "id);\n"
         "INSERT INTO parameter_set_approvals (parameter_set_id, leg_id, approved_by, run_id, note,"
         " approved_at_utc)\n"
         "  SELECT id, leg_id, 'run ' || run_id, run_id, 'identified by run ' || run_id ||"
         " ' on the bench, stored before approvals were recorded', created_at_utc\n"
         "  FROM parameter_sets WHERE run_id IS NOT NULL ORDER BY id;\n";
}

// What a hardware stimulator was told during a trial (api::DeviceCommandLog):
// one row per trial that has it, the columns as little-endian float64 BLOBs
// like trial_pulses, the single-pulse flags one byte each.
std::string DeviceCommandsMigration(const std::string& int_type, const std::string& real_type,
                                    const std::string& blob_type) {
  return "CREATE TABLE trial_device_commands (\n"
         "  trial_id            " + int_type + " PRIMARY KEY REFERENCES trials(id),\n"
         "  device              TEXT NOT NULL CHECK (length(device) BETWEEN 1 AND 64),\n"
         "  pulse_rate_hz       " + real_type + " NOT NULL CHECK (pulse_rate_hz > 0),\n"
         "  current_step_ma     " + real_type + " NOT NULL CHECK (current_step_ma > 0),\n"
         "  start_monotonic_ns  " + int_type + " NOT NULL,\n"
         "  command_count       " + int_type + " NOT NULL CHECK (command_count >= 0),\n"
         "  t_s_f64le           " + blob_type + " NOT NULL CHECK (length(t_s_f64le) = 8 * command_count),\n"
         "  requested_ma_f64le  " + blob_type +
         " NOT NULL CHECK (length(requested_ma_f64le) = 8 * command_count),\n"
         "  commanded_ma_f64le  " + blob_type +
         " NOT NULL CHECK (length(commanded_ma_f64le) = 8 * command_count),\n"
         "  single_pulse_u8     " + blob_type +
         " NOT NULL CHECK (length(single_pulse_u8) = command_count)\n"
         ");\n";
}

// ---------------------------------------------------------------- PostgreSQL
//
// The same schema in PostgreSQL's dialect, as of SQLite migration 11 (one
// migration: PostgreSQL support began there), then the migrations after 11
// in both engines. Differences, each with the same effect:
//  * ids are identity columns (BIGINT GENERATED BY DEFAULT AS IDENTITY);
//  * integers are BIGINT, reals DOUBLE PRECISION, BLOBs bytea;
//  * text compares byte by byte (COLLATE "C", SQLite's BINARY), so the
//    *_utc text order stays time order whatever the cluster's locale;
//  * json_valid(x) is a cast to jsonb, GLOB a regular expression;
//  * an index that SQLite ends with the rowid implicitly names id last, so
//    "ORDER BY <indexed>, id" reads in index order here too;
//  * the append-only triggers are one PL/pgSQL function raising SQLSTATE
//    P0001 with SQLite's messages (and TRUNCATE is refused as well).

const char* const kPostgresSchema11 = R"sql(
CREATE FUNCTION fesbench_append_only() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
  IF TG_OP = 'UPDATE' THEN
    RAISE EXCEPTION '% is append-only: add a correcting row instead', TG_TABLE_NAME;
  END IF;
  RAISE EXCEPTION '% is append-only: rows are never deleted', TG_TABLE_NAME;
END $$;

CREATE TABLE schema_migrations (
  version        BIGINT PRIMARY KEY,
  name           TEXT NOT NULL,
  applied_at_utc TEXT COLLATE "C" NOT NULL
);

CREATE TABLE subjects (
  id             BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
  code           TEXT COLLATE "C" NOT NULL UNIQUE CHECK (length(code) BETWEEN 1 AND 32),
  created_at_utc TEXT COLLATE "C" NOT NULL
);
CREATE TABLE subject_revisions (
  id                    BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
  subject_id            BIGINT NOT NULL REFERENCES subjects(id),
  revision              BIGINT NOT NULL CHECK (revision >= 1),
  age_years             BIGINT CHECK (age_years BETWEEN 0 AND 130),
  sex                   TEXT NOT NULL CHECK (sex IN ('female', 'male', 'other', 'undisclosed')),
  height_cm             DOUBLE PRECISION CHECK (height_cm > 0),
  weight_kg             DOUBLE PRECISION CHECK (weight_kg > 0),
  shank_length_cm       DOUBLE PRECISION CHECK (shank_length_cm > 0),
  calf_circumference_cm DOUBLE PRECISION CHECK (calf_circumference_cm > 0),
  corrects_id           BIGINT REFERENCES subject_revisions(id),
  reason                TEXT NOT NULL DEFAULT '',
  recorded_at_utc       TEXT COLLATE "C" NOT NULL,
  recorded_by           TEXT NOT NULL DEFAULT '',
  UNIQUE (subject_id, revision),
  CHECK ((revision = 1) = (corrects_id IS NULL))
);
CREATE UNIQUE INDEX subject_revisions_corrects ON subject_revisions(corrects_id)
  WHERE corrects_id IS NOT NULL;

CREATE TABLE legs (
  id             BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
  subject_id     BIGINT NOT NULL REFERENCES subjects(id),
  side           TEXT NOT NULL CHECK (side IN ('left', 'right')),
  created_at_utc TEXT COLLATE "C" NOT NULL,
  UNIQUE (subject_id, side),
  UNIQUE (id, subject_id)
);

CREATE TABLE sessions (
  id             BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
  subject_id     BIGINT NOT NULL REFERENCES subjects(id),
  leg_id         BIGINT NOT NULL,
  created_at_utc TEXT COLLATE "C" NOT NULL,
  FOREIGN KEY (leg_id, subject_id) REFERENCES legs(id, subject_id)
);
CREATE INDEX sessions_subject ON sessions(subject_id, id);
CREATE TABLE session_revisions (
  id                      BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
  session_id              BIGINT NOT NULL REFERENCES sessions(id),
  revision                BIGINT NOT NULL CHECK (revision >= 1),
  session_date            TEXT COLLATE "C" NOT NULL
                          CHECK (session_date ~ '^[0-9]{4}-[0-1][0-9]-[0-3][0-9]$'),
  accelerometer_placement TEXT NOT NULL,
  threshold_ma            DOUBLE PRECISION CHECK (threshold_ma BETWEEN 0 AND 100),
  max_tolerated_ma        DOUBLE PRECISION CHECK (max_tolerated_ma BETWEEN 0 AND 100),
  notes                   TEXT NOT NULL DEFAULT '',
  corrects_id             BIGINT REFERENCES session_revisions(id),
  reason                  TEXT NOT NULL DEFAULT '',
  recorded_at_utc         TEXT COLLATE "C" NOT NULL,
  recorded_by             TEXT NOT NULL DEFAULT '',
  UNIQUE (session_id, revision),
  CHECK ((revision = 1) = (corrects_id IS NULL)),
  CHECK (threshold_ma IS NULL OR max_tolerated_ma IS NULL OR threshold_ma <= max_tolerated_ma)
);
CREATE UNIQUE INDEX session_revisions_corrects ON session_revisions(corrects_id)
  WHERE corrects_id IS NOT NULL;

CREATE TABLE runs (
  id               BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
  session_id       BIGINT NOT NULL REFERENCES sessions(id),
  protocol_name    TEXT NOT NULL CHECK (length(protocol_name) > 0),
  protocol_version TEXT NOT NULL CHECK (length(protocol_version) > 0),
  parameters_json  TEXT NOT NULL CHECK (parameters_json::jsonb IS NOT NULL),
  created_at_utc   TEXT COLLATE "C" NOT NULL
);
CREATE INDEX runs_session ON runs(session_id, id);
CREATE TABLE run_events (
  id      BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
  run_id  BIGINT NOT NULL REFERENCES runs(id),
  state   TEXT NOT NULL
          CHECK (state IN ('queued', 'running', 'done', 'failed', 'aborted')),
  message TEXT NOT NULL DEFAULT '',
  at_utc  TEXT COLLATE "C" NOT NULL
);
CREATE INDEX run_events_run ON run_events(run_id, id);

CREATE TABLE users (
  id             BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
  name           TEXT COLLATE "C" NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 64),
  role           TEXT NOT NULL CHECK (role IN ('clinician', 'analyst', 'admin')),
  created_at_utc TEXT COLLATE "C" NOT NULL
);
CREATE TABLE user_deactivations (
  user_id BIGINT PRIMARY KEY REFERENCES users(id),
  reason  TEXT NOT NULL DEFAULT '',
  at_utc  TEXT COLLATE "C" NOT NULL
);
CREATE TABLE tokens (
  id             BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
  user_id        BIGINT NOT NULL REFERENCES users(id),
  token_sha256   BYTEA NOT NULL UNIQUE CHECK (length(token_sha256) = 32),
  label          TEXT NOT NULL DEFAULT '',
  created_at_utc TEXT COLLATE "C" NOT NULL,
  expires_at_utc TEXT COLLATE "C"
);
CREATE TABLE token_revocations (
  token_id BIGINT PRIMARY KEY REFERENCES tokens(id),
  at_utc   TEXT COLLATE "C" NOT NULL
);

CREATE TABLE audit_log (
  id              BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
  at_utc          TEXT COLLATE "C" NOT NULL,
  user_id         BIGINT REFERENCES users(id),
  actor           TEXT NOT NULL,
  action          TEXT NOT NULL CHECK (length(action) > 0),
  target          TEXT NOT NULL DEFAULT '',
  request_summary TEXT NOT NULL DEFAULT '',
  outcome         TEXT NOT NULL DEFAULT ''
);
CREATE INDEX audit_log_time ON audit_log(at_utc, id);
CREATE INDEX audit_log_user_id ON audit_log(user_id, id);

CREATE TABLE trials (
  id                 BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
  session_id         BIGINT NOT NULL REFERENCES sessions(id),
  run_id             BIGINT REFERENCES runs(id),
  name               TEXT,
  start_time_unix_ms BIGINT,
  created_at_utc     TEXT COLLATE "C" NOT NULL
);
CREATE INDEX trials_session ON trials(session_id, id);
CREATE INDEX trials_run ON trials(run_id) WHERE run_id IS NOT NULL;
CREATE TABLE trial_channels (
  id             BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
  trial_id       BIGINT NOT NULL REFERENCES trials(id),
  grp            TEXT NOT NULL CHECK (grp IN ('main', 'emg')),
  ordinal        BIGINT NOT NULL CHECK (ordinal >= 0),
  name           TEXT COLLATE "C" NOT NULL,
  unit           TEXT NOT NULL,
  sample_rate_hz DOUBLE PRECISION NOT NULL CHECK (sample_rate_hz > 0),
  sample_count   BIGINT NOT NULL CHECK (sample_count >= 0),
  samples_f64le  BYTEA NOT NULL CHECK (length(samples_f64le) = 8 * sample_count),
  UNIQUE (trial_id, grp, ordinal),
  UNIQUE (trial_id, grp, name)
);

CREATE TABLE parameter_sets (
  id               BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
  subject_id       BIGINT NOT NULL REFERENCES subjects(id),
  leg_id           BIGINT NOT NULL,
  version          BIGINT NOT NULL CHECK (version >= 1),
  model            TEXT NOT NULL,
  irc_method       TEXT NOT NULL DEFAULT '',
  passive_method   TEXT NOT NULL DEFAULT '',
  active_method    TEXT NOT NULL DEFAULT '',
  software_version TEXT NOT NULL DEFAULT '',
  supersedes_id    BIGINT REFERENCES parameter_sets(id),
  created_at_utc   TEXT COLLATE "C" NOT NULL,
  params_json      TEXT NOT NULL CHECK (params_json::jsonb IS NOT NULL),
  FOREIGN KEY (leg_id, subject_id) REFERENCES legs(id, subject_id),
  UNIQUE (subject_id, leg_id, version)
);
CREATE INDEX parameter_sets_subject_time ON parameter_sets(subject_id, created_at_utc, id);
CREATE INDEX parameter_sets_leg_time ON parameter_sets(subject_id, leg_id, created_at_utc, id);
CREATE INDEX parameter_sets_subject_id ON parameter_sets(subject_id, id);
CREATE INDEX parameter_sets_leg_id ON parameter_sets(subject_id, leg_id, id);
CREATE TABLE parameter_set_trials (
  parameter_set_id BIGINT NOT NULL REFERENCES parameter_sets(id),
  trial_id         BIGINT NOT NULL REFERENCES trials(id),
  PRIMARY KEY (parameter_set_id, trial_id)
);
CREATE INDEX parameter_set_trials_trial ON parameter_set_trials(trial_id);

CREATE TABLE predictions (
  id               BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
  parameter_set_id BIGINT NOT NULL REFERENCES parameter_sets(id),
  trial_id         BIGINT REFERENCES trials(id),
  input_json       TEXT NOT NULL CHECK (input_json::jsonb IS NOT NULL),
  output_json      TEXT NOT NULL CHECK (output_json::jsonb IS NOT NULL),
  created_at_utc   TEXT COLLATE "C" NOT NULL
);
CREATE INDEX predictions_parameter_set ON predictions(parameter_set_id, id);
CREATE TABLE evaluations (
  id               BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
  parameter_set_id BIGINT NOT NULL REFERENCES parameter_sets(id),
  trial_id         BIGINT NOT NULL REFERENCES trials(id),
  prediction_id    BIGINT REFERENCES predictions(id),
  channel          TEXT NOT NULL,
  unit             TEXT NOT NULL,
  rms_error        DOUBLE PRECISION NOT NULL CHECK (rms_error >= 0),
  max_abs_error    DOUBLE PRECISION NOT NULL CHECK (max_abs_error >= 0),
  details_json     TEXT NOT NULL DEFAULT '{}' CHECK (details_json::jsonb IS NOT NULL),
  created_at_utc   TEXT COLLATE "C" NOT NULL
);
CREATE INDEX evaluations_parameter_set ON evaluations(parameter_set_id, id);
CREATE INDEX evaluations_trial ON evaluations(trial_id, id);

CREATE TABLE estop_events (
  id          BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY,
  latched     BIGINT NOT NULL CHECK (latched IN (0, 1)),
  source      TEXT NOT NULL DEFAULT '',
  recorded_by TEXT NOT NULL DEFAULT '',
  at_utc      TEXT COLLATE "C" NOT NULL
);

CREATE TABLE trial_pulses (
  trial_id        BIGINT PRIMARY KEY REFERENCES trials(id),
  pulse_rate_hz   DOUBLE PRECISION NOT NULL CHECK (pulse_rate_hz > 0),
  pulse_width_us  DOUBLE PRECISION NOT NULL CHECK (pulse_width_us > 0),
  pulse_count     BIGINT NOT NULL CHECK (pulse_count >= 0),
  t_s_f64le       BYTEA NOT NULL CHECK (length(t_s_f64le) = 8 * pulse_count),
  stim_ma_f64le   BYTEA NOT NULL CHECK (length(stim_ma_f64le) = 8 * pulse_count)
);

CREATE TABLE trial_imports (
  trial_id          BIGINT PRIMARY KEY REFERENCES trials(id),
  format            TEXT NOT NULL,
  source            TEXT NOT NULL DEFAULT '',
  spec_json         TEXT NOT NULL DEFAULT '{}',
  imported_by       TEXT NOT NULL DEFAULT '',
  original_trial_id BIGINT
);
)sql";

std::string PostgresAppendOnly(std::initializer_list<const char*> tables) {
  std::string sql;
  for (const char* table : tables) {
    const std::string t(table);
    sql += "CREATE TRIGGER " + t + "_append_only BEFORE UPDATE OR DELETE ON " + t +
           " FOR EACH ROW EXECUTE FUNCTION fesbench_append_only();\n";
    sql += "CREATE TRIGGER " + t + "_no_truncate BEFORE TRUNCATE ON " + t +
           " FOR EACH STATEMENT EXECUTE FUNCTION fesbench_append_only();\n";
  }
  return sql;
}

}  // namespace

// A run's bench time as it ran and as planned, s, on its final event.
std::string RunBenchTimeMigration(const std::string& real_type) {
  return "ALTER TABLE run_events ADD COLUMN bench_s " + real_type + " CHECK (bench_s >= 0);\n"
         "ALTER TABLE run_events ADD COLUMN bench_planned_s " + real_type +
         " CHECK (bench_planned_s >= 0);\n";
}

// A subject's range of motion (the knee's, deg), both ends or neither.
std::string RangeOfMotionMigration(const std::string& real_type) {
  return "ALTER TABLE subject_revisions ADD COLUMN rom_min_deg " + real_type +
         " CHECK (rom_min_deg BETWEEN -30 AND 60);\n"
         "ALTER TABLE subject_revisions ADD COLUMN rom_max_deg " + real_type +
         " CHECK (rom_max_deg BETWEEN 60 AND 180);\n";
}

// A run's outcome (api/run_outcome.h, docs/ARCHITECTURE.md "Runs"), written
// once with its terminal event; runs that ended before get theirs from
// BackfillRunOutcomes, which run_events' append-only trigger is lifted for
// (`lift`, `restore`: each engine's DDL).
Migration RunOutcomeMigration(const std::string& lift, const std::string& restore) {
  Migration m{19, "a run's outcome, stored with its end",
              "ALTER TABLE run_events ADD COLUMN outcome_json TEXT;\n" + lift};
  m.backfill = &BackfillRunOutcomes;
  m.sql_after = restore;
  return m;
}

const std::vector<Migration>& AllMigrations() {
  static const std::vector<Migration> kMigrations = {
      {1, "subjects, legs, sessions, runs, users, tokens, audit log",
       std::string(kMigration1) +
           AppendOnly({"schema_migrations", "subjects", "subject_revisions", "legs", "sessions",
                       "session_revisions", "runs", "run_events", "users", "user_deactivations",
                       "tokens", "token_revocations", "audit_log"})},
      {2, "trials and their channels",
       std::string(kMigration2) + AppendOnly({"trials", "trial_channels"})},
      {3, "parameter sets and their provenance trials",
       std::string(kMigration3) + AppendOnly({"parameter_sets", "parameter_set_trials"})},
      {4, "predictions and evaluations",
       std::string(kMigration4) + AppendOnly({"predictions", "evaluations"})},
      {5, "who recorded each subject and session revision", kMigration5},
      {6, "run states named as everywhere else (done, aborted)",
       std::string(kMigration6) + AppendOnly({"run_events"})},
      {7, "the e-stop latch, kept across restarts",
       std::string(kMigration7) + AppendOnly({"estop_events"})},
      {8, "the pulses delivered in each trial",
       std::string(kMigration8) + AppendOnly({"trial_pulses"})},
      {9, "indexes for keyset paging of parameter sets", kMigration9},
      {10, "index for keyset paging of the audit log by user", kMigration10},
      {11, "where imported trials came from",
       std::string(kMigration11) + AppendOnly({"trial_imports"})},
      {12, "runs and e-stop presses belong to a bench", kMigration12},
      {13, "parameter sets name the run that identified them", kMigration13},
      {14, "every trial names its kind",
       TrialKindMigration("DROP TRIGGER trials_no_update;\n", AppendOnlyUpdate("trials"))},
      {15, "clinicians approve parameter sets",
       ApprovalMigration("INTEGER PRIMARY KEY", "INTEGER", "TEXT") +
           AppendOnly({"parameter_set_approvals"})},
      {16, "what a hardware stimulator was told in each trial",
       DeviceCommandsMigration("INTEGER", "REAL", "BLOB") +
           AppendOnly({"trial_device_commands"})},
      {17, "a subject's range of motion", RangeOfMotionMigration("REAL")},
      {18, "a run's bench time as it ran", RunBenchTimeMigration("REAL")},
      RunOutcomeMigration("DROP TRIGGER run_events_no_update;\n", AppendOnlyUpdate("run_events")),
  };
  return kMigrations;
}

const std::vector<Migration>& PostgresMigrations() {
  static const std::vector<Migration> kMigrations = {
      {11, "the schema of SQLite migrations 1-11 in PostgreSQL",
       std::string(kPostgresSchema11) +
           PostgresAppendOnly({"schema_migrations", "subjects", "subject_revisions", "legs",
                               "sessions", "session_revisions", "runs", "run_events", "users",
                               "user_deactivations", "tokens", "token_revocations", "audit_log",
                               "trials", "trial_channels", "parameter_sets",
                               "parameter_set_trials", "predictions", "evaluations",
                               "estop_events", "trial_pulses", "trial_imports"})},
      {12, "runs and e-stop presses belong to a bench", kMigration12},
      {13, "parameter sets name the run that identified them", kMigration13},
      {14, "every trial names its kind",
       TrialKindMigration("ALTER TABLE trials DISABLE TRIGGER trials_append_only;\n",
                          "ALTER TABLE trials ENABLE TRIGGER trials_append_only;\n")},
      {15, "clinicians approve parameter sets",
       ApprovalMigration("BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY", "BIGINT",
                         "TEXT COLLATE \"C\"") +
           PostgresAppendOnly({"parameter_set_approvals"})},
      {16, "what a hardware stimulator was told in each trial",
       DeviceCommandsMigration("BIGINT", "DOUBLE PRECISION", "BYTEA") +
           PostgresAppendOnly({"trial_device_commands"})},
      {17, "a subject's range of motion", RangeOfMotionMigration("DOUBLE PRECISION")},
      {18, "a run's bench time as it ran", RunBenchTimeMigration("DOUBLE PRECISION")},
      RunOutcomeMigration("ALTER TABLE run_events DISABLE TRIGGER run_events_append_only;\n",
                          "ALTER TABLE run_events ENABLE TRIGGER run_events_append_only;\n"),
  };
  return kMigrations;
}

int LatestSchemaVersion() { return AllMigrations().back().version; }

}  // namespace fesbench::storage
