#pragma once

/// @file
/// JSON wire form of the stored resources (docs/API.md) and strict readers
/// of their request bodies. Keys carry units; times are UTC ISO 8601
/// ("2026-11-21T10:36:43.123456Z"). Readers refuse unknown fields, wrong
/// types and out-of-range values with kInvalidArgument naming the field.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "api/status.h"
#include "storage/audit_log.h"
#include "storage/parameter_sets.h"
#include "storage/sessions.h"
#include "storage/subjects.h"
#include "storage/trials.h"
#include "storage/users.h"

namespace fesbench::server::http {

/// {"age_years", "sex", "height_cm", "weight_kg", "shank_length_cm",
///  "calf_circumference_cm"} (unmeasured values omitted).
nlohmann::json SubjectDetailsToJson(const storage::SubjectDetails& details);
/// {"id", "code", "created_at_utc", "revision", "details": {...},
///  "legs": [{"id", "side"}]}.
nlohmann::json SubjectToJson(const storage::Subject& subject, const std::vector<storage::Leg>& legs);
/// {"id", "date", "subject_id", "leg_id", "leg", "created_at_utc", "revision",
///  "details": {"date", "accelerometer_placement", "threshold_ma",
///  "max_tolerated_ma", "notes"}}.
nlohmann::json SessionToJson(const storage::Session& session, std::string_view leg_side);
/// {"id", "session_id", "run_id", "name", "kind" (the protocol's trial name),
///  "num_samples", "sample_rate_hz", "duration_s", "created_at_utc"}.
nlohmann::json TrialSummaryToJson(const storage::TrialSummary& trial);
/// {"id", "subject_id", "leg_id", "version", "model", "irc_method",
///  "passive_method", "active_method", "software_version", "supersedes_id",
///  "created_at_utc"}.
nlohmann::json ParameterSetSummaryToJson(const storage::ParameterSetSummary& summary);
/// A set's approval state (docs/API.md, parameter-set approval): {"approved":
/// the set is its leg's approved set now, "approval": its newest approval
/// {"approved_by", "approved_by_user_id", "approved_at_utc", "note",
/// "run_id"} or null when never approved}.
nlohmann::json ApprovalFieldsToJson(const std::optional<storage::Approval>& newest);
/// The summary plus "parameters" (api::ParameterSetToJson) and "trial_ids".
nlohmann::json StoredParameterSetToJson(const storage::StoredParameterSet& set);
/// {"id", "name", "role", "active", "created_at_utc"}.
nlohmann::json UserToJson(const storage::User& user);
/// {"id", "at_utc", "user_id", "actor", "action", "target", "request_summary", "outcome"}.
nlohmann::json AuditEntryToJson(const storage::AuditEntry& entry);

/// POST /subjects: {"code", "details"?: {...}, "legs"?: ["left"|"right"]}.
struct NewSubjectRequest {
  std::string code;
  storage::SubjectDetails details;
  std::vector<storage::Side> legs;
};
api::Result<NewSubjectRequest> NewSubjectFromJson(const nlohmann::json& body);
/// The details object at `path` (all fields optional; ranges as
/// storage::ValidateSubjectDetails).
api::Result<storage::SubjectDetails> SubjectDetailsFromJson(const nlohmann::json& json,
                                                            const std::string& path);

/// POST /subjects/{id}/sessions: {"leg": "left"|"right", "date",
/// "accelerometer_placement"?, "threshold_ma"?, "max_tolerated_ma"?, "notes"?}.
struct NewSessionRequest {
  storage::Side leg = storage::Side::kRight;
  storage::SessionDetails details;
};
api::Result<NewSessionRequest> NewSessionFromJson(const nlohmann::json& body);

/// PATCH /subjects/{id} and /sessions/{id} (docs/API.md, "Corrections"): {"reason",
/// "details": {...}}. The given fields replace the current ones, null
/// clears one, the others are kept. `changed` lists the given fields.
struct SubjectCorrection {
  std::string reason;
  storage::SubjectDetails details;
  std::vector<std::string> changed;
};
struct SessionCorrection {
  std::string reason;
  storage::SessionDetails details;
  std::vector<std::string> changed;
};
/// kInvalidArgument naming the field ("reason", "details.weight_kg") with
/// the unit and allowed range in the message.
api::Result<SubjectCorrection> SubjectCorrectionFromJson(const nlohmann::json& body,
                                                         const storage::SubjectDetails& current);
api::Result<SessionCorrection> SessionCorrectionFromJson(const nlohmann::json& body,
                                                         const storage::SessionDetails& current);
/// {"revision", "corrects_revision" (null for 1), "reason", "changed_by"
///  (user name or null), "changed_at_utc", "details"}.
nlohmann::json SubjectRevisionToJson(const storage::SubjectRevision& revision,
                                     std::optional<int> corrects_revision);
nlohmann::json SessionRevisionToJson(const storage::SessionRevision& revision,
                                     std::optional<int> corrects_revision);

/// POST /users: {"name", "role"}.
struct NewUserRequest {
  std::string name;
  storage::Role role = storage::Role::kAnalyst;
};
api::Result<NewUserRequest> NewUserFromJson(const nlohmann::json& body);

/// POST /tokens: {"user_id", "label"?, "expires_in_s"?} (expiry 60 s – 10 years).
struct NewTokenRequest {
  std::int64_t user_id = 0;
  std::string label;
  std::optional<std::int64_t> expires_in_s;
};
api::Result<NewTokenRequest> NewTokenFromJson(const nlohmann::json& body);

}  // namespace fesbench::server::http
