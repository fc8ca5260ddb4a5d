#include "storage/audit_log.h"

#include "storage/row_helpers.h"

namespace fesbench::storage {

api::Result<std::int64_t> AuditLog::Append(const NewAuditEntry& entry) {
  if (entry.action.empty()) {
    return api::Status::InvalidArgument("audit action must not be empty", "action");
  }
  return db_.Write([&](Connection& c) -> api::Result<std::int64_t> {
    if (entry.user_id) {
      if (auto s =
              internal::RequireRow(c, "SELECT 1 FROM users WHERE id = ?1", *entry.user_id, "user");
          !s.ok()) {
        return s;
      }
    }
    return internal::InsertRow(
        c,
        "INSERT INTO audit_log (at_utc, user_id, actor, action, target, request_summary, outcome)"
        " VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
        api::FormatUtc(db_.Now()), entry.user_id, entry.actor, entry.action, entry.target,
        entry.request_summary, entry.outcome);
  });
}

api::Result<std::vector<AuditEntry>> AuditLog::List(const AuditQuery& query) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<AuditEntry>> {
    std::optional<std::string> from;
    std::optional<std::string> to;
    if (query.from) from = api::FormatUtc(*query.from);
    if (query.to) to = api::FormatUtc(*query.to);
    return internal::QueryRows(
        c,
        "SELECT id, at_utc, user_id, actor, action, target, request_summary, outcome"
        " FROM audit_log WHERE (CAST(?1 AS TEXT) IS NULL OR at_utc >= ?1)"
        " AND (CAST(?2 AS TEXT) IS NULL OR at_utc < ?2)"
        " AND (CAST(?3 AS BIGINT) IS NULL OR user_id = ?3)"
        " AND (CAST(?5 AS BIGINT) IS NULL OR id < ?5)"
        " ORDER BY id DESC LIMIT ?4",
        [](const Statement& s) -> api::Result<AuditEntry> {
          AuditEntry e;
          e.id = s.Int64(0);
          const auto at = api::ParseUtc(s.Text(1));
          if (!at) return internal::BadStoredValue("audit entry");
          e.at = *at;
          e.entry.user_id = s.OptionalInt64(2);
          e.entry.actor = s.Text(3);
          e.entry.action = s.Text(4);
          e.entry.target = s.Text(5);
          e.entry.request_summary = s.Text(6);
          e.entry.outcome = s.Text(7);
          return e;
        },
        from, to, query.user_id, static_cast<std::int64_t>(query.limit), query.before_id);
  });
}

}  // namespace fesbench::storage
