#pragma once

/// @file
/// Parameter sets (docs/MODEL.md; docs/ARCHITECTURE.md): immutable versions with provenance.
/// Each is stored as its JSON text (api/parameter_set_json.h) plus indexed
/// columns (subject, leg, model, methods, software version, created_at UTC),
/// so a subject's history is an index range scan on (subject_id,
/// created_at_utc). A refit is a new version that may name the version it
/// supersedes; nothing is overwritten.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "api/status.h"
#include "model/parameter_set.h"
#include "storage/database.h"

namespace fesbench::storage {

struct NewParameterSet {
  std::int64_t subject_id = 0;
  std::int64_t leg_id = 0;
  model::ParameterSet params;  ///< provenance.trial_ids / active_trial_id must be stored trials.
  std::optional<std::int64_t> supersedes_id;  ///< an earlier set of the same subject and leg.
  std::optional<api::UtcTime> created_at;          ///< default: the database clock.
  std::optional<std::int64_t> run_id{};       ///< the run that identified it, if one did.
};

/// The indexed columns of a stored set.
struct ParameterSetSummary {
  std::int64_t id = 0;
  std::int64_t subject_id = 0;
  std::int64_t leg_id = 0;
  int version = 1;  ///< 1, 2, … per subject and leg.
  std::string model;
  std::string irc_method;
  std::string passive_method;
  std::string active_method;
  std::string software_version;
  std::optional<std::int64_t> supersedes_id;
  api::UtcTime created_at;
  std::optional<std::int64_t> run_id;  ///< the run that identified it (migration 13).
};

struct StoredParameterSet {
  ParameterSetSummary summary;
  model::ParameterSet params;
  std::vector<std::int64_t> trial_ids;  ///< provenance trials, ascending.
};

/// History filter: one subject; optionally one leg, one method (matching
/// the IRC, passive or active method) and a time range [from, to).
struct HistoryQuery {
  std::int64_t subject_id = 0;
  std::optional<std::int64_t> leg_id;
  std::optional<std::string> method;
  std::optional<api::UtcTime> from;
  std::optional<api::UtcTime> to;
  std::size_t limit = 1000;  ///< oldest first, at most this many.
};

/// One page of the parameter-set list (GET /parameter-sets): every filter
/// in the query, ascending by id from `after_id` (keyset paging on the
/// primary key, or on (subject_id, id) / (subject_id, leg_id, id) when
/// filtered: O(log n + limit) however deep the page).
struct ParameterSetListQuery {
  std::optional<std::int64_t> subject_id;
  std::optional<std::int64_t> leg_id;  ///< with subject_id.
  std::optional<std::string> method;   ///< IRC, passive or active method name.
  std::optional<api::UtcTime> from;         ///< created at or after.
  std::optional<api::UtcTime> to;           ///< created before.
  std::int64_t after_id = 0;
  std::size_t limit = 50;
};

/// A clinician's approval of a set for its leg (migration 15). The leg's
/// approved set, the one gating stimulation (docs/SAFETY.md), is the set of
/// the leg's newest approval; approvals are never withdrawn, only followed.
struct NewApproval {
  std::int64_t parameter_set_id = 0;
  std::optional<std::int64_t> approved_by_user_id;  ///< unset: no user row (a migration).
  std::string approved_by;                          ///< the user's name, not empty.
  std::optional<std::int64_t> run_id;    ///< the bench run whose own measurement the set is.
  std::string note;                      ///< why, 1–500 bytes.
  std::optional<api::UtcTime> approved_at{};  ///< default: the database clock.
};

struct Approval {
  std::int64_t id = 0;
  std::int64_t parameter_set_id = 0;
  std::int64_t leg_id = 0;
  std::optional<std::int64_t> approved_by_user_id;
  std::string approved_by;
  std::optional<std::int64_t> run_id;
  std::string note;
  api::UtcTime approved_at;
  bool current = false;  ///< the leg's newest approval: its set is the leg's approved set.
};

/// The software version recorded when a set's provenance names none.
std::string_view StorageSoftwareVersion();

class ParameterSetRepository {
 public:
  explicit ParameterSetRepository(Database& db) : db_(db) {}

  /// Stores a new version. The set is validated through its JSON form
  /// (kInvalidArgument with the field path). kNotFound for an unknown
  /// subject, leg, trial or superseded set; kInvalidArgument for a leg or
  /// trial of another subject ("leg_id", "provenance.trial_ids[i]") or a
  /// superseded set of another subject or leg ("supersedes_id"). An empty
  /// provenance.software_version is filled with StorageSoftwareVersion().
  api::Result<ParameterSetSummary> Insert(const NewParameterSet& set);
  /// kNotFound for an unknown id; kDataLoss if the stored JSON is unreadable.
  api::Result<StoredParameterSet> Get(std::int64_t id);
  /// Summaries matching `query`, oldest first (kNotFound for an unknown subject).
  api::Result<std::vector<ParameterSetSummary>> History(const HistoryQuery& query);
  /// A page of summaries matching `query` (kNotFound for an unknown subject).
  api::Result<std::vector<ParameterSetSummary>> List(const ParameterSetListQuery& query);
  /// The latest version for a subject and leg (kNotFound if there is none).
  api::Result<StoredParameterSet> Latest(std::int64_t subject_id, std::int64_t leg_id);

  /// Records an approval; the set becomes its leg's approved set. kNotFound
  /// for an unknown set or run; kInvalidArgument "note" for an empty note or
  /// one over 500 bytes; kFailedPrecondition when the set already is its
  /// leg's approved set.
  api::Result<Approval> Approve(const NewApproval& approval);
  /// The leg's approved set (kNotFound "no parameter set is approved for
  /// leg N" when no set of the leg was ever approved).
  api::Result<StoredParameterSet> Approved(std::int64_t leg_id);
  /// The leg's newest approval, if any set of it was approved.
  api::Result<std::optional<Approval>> LegApproval(std::int64_t leg_id);
  /// Each set's newest approval (sets never approved are absent), read in
  /// one transaction.
  api::Result<std::vector<Approval>> LatestApprovals(const std::vector<std::int64_t>& set_ids);
  /// A set's approvals, oldest first.
  api::Result<std::vector<Approval>> Approvals(std::int64_t parameter_set_id);
  /// The leg's sets a clinician approved at some time, newest approval
  /// first, each once, at most `limit`.
  api::Result<std::vector<std::int64_t>> ApprovedHistory(std::int64_t leg_id, std::size_t limit);
  /// Ids of the sets identified from at least one trial of the session,
  /// ascending (kNotFound for an unknown session).
  api::Result<std::vector<std::int64_t>> IdsForSession(std::int64_t session_id);
  /// The set run `run_id` stored, if it stored one (the newest if several).
  api::Result<std::optional<std::int64_t>> IdForRun(std::int64_t run_id);
  /// The stored JSON text, pretty-printed (2-space indent).
  api::Result<std::string> ExportJson(std::int64_t id);

 private:
  Database& db_;
};

}  // namespace fesbench::storage
