#pragma once

/// @file
/// Recorded trials (docs/ARCHITECTURE.md, storage): every channel with its name, unit and
/// sample rate; samples as one BLOB per channel of little-endian IEEE-754
/// float64 values; the delivered pulses (api::PulseRecord), if any, as two
/// such BLOBs in trial_pulses. Trials are immutable once stored.

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "api/status.h"
#include "api/trial.h"
#include "api/trial_summary.h"
#include "storage/database.h"

namespace fesbench::storage {

/// Where a trial belongs.
struct TrialOwner {
  std::int64_t session_id = 0;
  std::optional<std::int64_t> run_id;  ///< the run that recorded it, if any.
};

/// A stored trial's metadata without samples (api/trial_summary.h).
using api::TrialSummary;

/// Where an imported trial came from (POST /sessions/{id}/trials): kept
/// beside the trial, which is otherwise an ordinary trial.
struct TrialImport {
  std::string format;       ///< "csv", "tsv", "sto" or "archive".
  std::string source;       ///< what the importer said it is (file, rig, lab).
  std::string spec_json;    ///< the import spec (column mapping and units), JSON.
  std::string imported_by;  ///< the user who imported it.
  std::optional<std::int64_t> original_trial_id;  ///< its id where it was exported from.
  friend bool operator==(const TrialImport&, const TrialImport&) = default;
};

class TrialRepository {
 public:
  explicit TrialRepository(Database& db) : db_(db) {}

  /// Stores a trial (its channels in one transaction) and returns its id.
  /// The trial is validated with api::ValidateTrial (kInvalidArgument with
  /// the field path). kNotFound for an unknown session or run;
  /// kInvalidArgument (field "run_id") for a run of another session.
  /// `trial.id` is ignored.
  /// `import`, if given, is stored as the trial's provenance. Inside a
  /// caller's Database::Write it joins that transaction.
  api::Result<std::int64_t> Insert(const TrialOwner& owner, const api::Trial& trial,
                                   const std::optional<TrialImport>& import = std::nullopt);
  /// The session's trials imported from archives: original id → id.
  api::Result<std::map<std::int64_t, std::int64_t>> ImportedOriginals(std::int64_t session_id);
  /// The import provenance of a trial (nullopt for a bench trial);
  /// kNotFound for an unknown trial.
  api::Result<std::optional<TrialImport>> ImportOf(std::int64_t trial_id);
  /// The whole trial with `id` set. kNotFound for an unknown id.
  api::Result<api::Trial> Get(std::int64_t trial_id);
  /// The owner of a stored trial.
  api::Result<TrialOwner> Owner(std::int64_t trial_id);
  /// Summaries of a session's trials, oldest first.
  api::Result<std::vector<TrialSummary>> ListForSession(std::int64_t session_id);
  /// At most `limit` of them with id > `after_id` (keyset paging on index
  /// trials_session: O(log n + limit) however deep the page).
  api::Result<std::vector<TrialSummary>> ListForSessionPage(std::int64_t session_id,
                                                            std::int64_t after_id,
                                                            std::size_t limit);
  /// Ids of the trials a run recorded, oldest first (index trials_run:
  /// O(log n), whatever the session's size).
  api::Result<std::vector<std::int64_t>> IdsOfRun(std::int64_t run_id);

 private:
  Database& db_;
};

}  // namespace fesbench::storage
