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
    auto insert = c.Prepare(
        "INSERT INTO audit_log (at_utc, user_id, actor, action, target, request_summary, outcome)"
        " VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)");
    if (!insert.ok()) return insert.status();
    insert->Bind(1, FormatUtc(db_.Now()))
        .Bind(2, entry.user_id)
        .Bind(3, entry.actor)
        .Bind(4, entry.action)
        .Bind(5, entry.target)
        .Bind(6, entry.request_summary)
        .Bind(7, entry.outcome);
    if (auto s = insert->Run(); !s.ok()) return s;
    return c.LastInsertRowId();
  });
}

api::Result<std::vector<AuditEntry>> AuditLog::List(const AuditQuery& query) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<AuditEntry>> {
    auto statement = c.Prepare(
        "SELECT id, at_utc, user_id, actor, action, target, request_summary, outcome"
        " FROM audit_log WHERE (?1 IS NULL OR at_utc >= ?1) AND (?2 IS NULL OR at_utc < ?2)"
        " AND (?3 IS NULL OR user_id = ?3) ORDER BY id DESC LIMIT ?4");
    if (!statement.ok()) return statement.status();
    std::optional<std::string> from;
    std::optional<std::string> to;
    if (query.from) from = FormatUtc(*query.from);
    if (query.to) to = FormatUtc(*query.to);
    statement->Bind(1, from)
        .Bind(2, to)
        .Bind(3, query.user_id)
        .Bind(4, static_cast<std::int64_t>(query.limit));
    std::vector<AuditEntry> entries;
    while (true) {
      auto row = statement->Step();
      if (!row.ok()) return row.status();
      if (!*row) break;
      AuditEntry e;
      e.id = statement->Int64(0);
      const auto at = ParseUtc(statement->Text(1));
      if (!at) return internal::BadStoredValue("audit entry");
      e.at = *at;
      e.entry.user_id = statement->OptionalInt64(2);
      e.entry.actor = statement->Text(3);
      e.entry.action = statement->Text(4);
      e.entry.target = statement->Text(5);
      e.entry.request_summary = statement->Text(6);
      e.entry.outcome = statement->Text(7);
      entries.push_back(std::move(e));
    }
    return entries;
  });
}

}  // namespace fesbench::storage
