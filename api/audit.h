#pragma once

/// @file
/// The audit log's entries on the wire (docs/API.md, `audit`;
/// docs/ARCHITECTURE.md, storage: the append-only log of state-changing
/// requests). Storage keeps entries as these types (storage/audit_log.h).
/// Readers as api/subject.h.

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "api/clock.h"
#include "api/status.h"

namespace fesbench::api {

/// What is appended: who did what to which record, and how it ended.
struct NewAuditEntry {
  std::optional<std::int64_t> user_id;  ///< the authenticated user, if any.
  std::string actor;                    ///< e.g. the user name, "system", a client address.
  std::string action;                   ///< e.g. "POST /api/v1/subjects"; must not be empty.
  std::string target;                   ///< e.g. "subjects/12".
  std::string request_summary;          ///< short summary; never secrets or tokens.
  std::string outcome;                  ///< e.g. "201", "409 already_exists".
  friend bool operator==(const NewAuditEntry&, const NewAuditEntry&) = default;
};

/// An appended entry.
struct AuditEntry {
  std::int64_t id = 0;
  UtcTime at;
  NewAuditEntry entry;
  friend bool operator==(const AuditEntry&, const AuditEntry&) = default;
};
/// {"id", "at_utc", "user_id", "actor", "action", "target",
///  "request_summary", "outcome"}.
nlohmann::json AuditEntryToJson(const AuditEntry& entry);
Result<AuditEntry> AuditEntryFromJson(const nlohmann::json& json);

}  // namespace fesbench::api
