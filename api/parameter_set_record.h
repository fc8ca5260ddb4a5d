#pragma once

/// @file
/// A stored parameter set on the wire (docs/API.md, "Parameter sets" and
/// "parameter-set approval"): its summary in the lists, the whole set with
/// its provenance trials and fit notes, and its approval state. Readers as
/// api/subject.h; the parameters themselves are docs/MODEL.md JSON
/// (api/parameter_set_json.h).

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "api/clock.h"
#include "api/status.h"
#include "model/parameter_set.h"

namespace fesbench::api {

/// A set's newest approval.
struct Approval {
  std::string approved_by;  ///< the user's name.
  std::optional<std::int64_t> approved_by_user_id;
  UtcTime approved_at;
  std::string note;                    ///< why.
  std::optional<std::int64_t> run_id;  ///< the bench run whose own measurement the set is.
  friend bool operator==(const Approval&, const Approval&) = default;
};

/// A set's approval state: `approved` when it is its leg's approved set
/// now; `newest` its newest approval (none when never approved).
struct ApprovalState {
  bool approved = false;
  std::optional<Approval> newest;
  friend bool operator==(const ApprovalState&, const ApprovalState&) = default;
};
/// {"approved", "approval": {"approved_by", "approved_by_user_id",
///  "approved_at_utc", "note", "run_id"} or null}: fields of the set's
/// object, not an object of their own.
nlohmann::json ApprovalStateToJson(const ApprovalState& state);
Result<ApprovalState> ApprovalStateFromJson(const nlohmann::json& json);

/// One set in the lists (GET /parameter-sets).
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
  std::optional<std::int64_t> supersedes_id;  ///< an earlier set of the same leg.
  UtcTime created_at;
  /// The approval fields, where the answer has them (lists, GET of one set,
  /// approvals).
  std::optional<ApprovalState> approval;
  friend bool operator==(const ParameterSetSummary&, const ParameterSetSummary&) = default;
};
/// {"id", "subject_id", "leg_id", "version", "model", "irc_method",
///  "passive_method", "active_method", "software_version", "supersedes_id",
///  "created_at_utc"} plus the approval fields when known.
nlohmann::json ParameterSetSummaryToJson(const ParameterSetSummary& summary);
/// The approval is read when "approved" is present.
Result<ParameterSetSummary> ParameterSetSummaryFromJson(const nlohmann::json& json);

/// One set with its parameters (GET /parameter-sets/{id}).
struct StoredParameterSet {
  ParameterSetSummary summary;
  std::vector<std::int64_t> trial_ids;  ///< provenance trials, ascending.
  /// The parameters (docs/MODEL.md JSON); none when the answer has none.
  std::optional<model::ParameterSet> parameters;
  /// The fit's warnings in a clinician's words (parameters.provenance.warnings
  /// keeps them as the fitting software wrote them).
  std::vector<std::string> fit_notes;
  friend bool operator==(const StoredParameterSet&, const StoredParameterSet&) = default;
};
/// The summary plus "trial_ids", "parameters" and "fit_notes".
nlohmann::json StoredParameterSetToJson(const StoredParameterSet& set);
Result<StoredParameterSet> StoredParameterSetFromJson(const nlohmann::json& json);

}  // namespace fesbench::api
