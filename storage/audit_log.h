#pragma once

/// @file
/// The append-only audit log of state-changing requests (docs/ARCHITECTURE.md, storage):
/// who, what, when (UTC) and a summary of the request. Triggers refuse any
/// UPDATE or DELETE of its rows.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "api/audit.h"
#include "api/status.h"
#include "storage/database.h"

namespace fesbench::storage {

// The entries are the wire's (api/audit.h).
using api::AuditEntry;
using api::NewAuditEntry;

struct AuditQuery {
  std::optional<api::UtcTime> from;  ///< inclusive.
  std::optional<api::UtcTime> to;    ///< exclusive.
  std::optional<std::int64_t> user_id;
  std::size_t limit = 1000;  ///< at most this many, newest first.
  /// Keyset paging: only entries older than this id (the last one of the
  /// previous page). A page is an index range, however deep.
  std::optional<std::int64_t> before_id;
};

class AuditLog {
 public:
  explicit AuditLog(Database& db) : db_(db) {}

  /// Appends an entry stamped with the database clock; its id.
  /// kInvalidArgument (field "action") for an empty action, kNotFound for an
  /// unknown user id. Joins the caller's transaction inside Database::Write.
  api::Result<std::int64_t> Append(const NewAuditEntry& entry);
  /// Entries matching `query`, newest first.
  api::Result<std::vector<AuditEntry>> List(const AuditQuery& query);

 private:
  Database& db_;
};

}  // namespace fesbench::storage
