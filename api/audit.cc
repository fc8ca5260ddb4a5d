#include "api/audit.h"

#include <utility>

#include "api/json_fields.h"
#include "api/json_read.h"
#include "api/time_utc.h"

namespace fesbench::api {

nlohmann::json AuditEntryToJson(const AuditEntry& e) {
  return {{"id", e.id},
          {"at_utc", FormatUtc(e.at)},
          {"user_id", OrNull(e.entry.user_id)},
          {"actor", e.entry.actor},
          {"action", e.entry.action},
          {"target", e.entry.target},
          {"request_summary", e.entry.request_summary},
          {"outcome", e.entry.outcome}};
}

Result<AuditEntry> AuditEntryFromJson(const nlohmann::json& j) {
  JsonFields in(j);
  AuditEntry e;
  e.id = in.Integer("id", true).value_or(0);
  ReadTime(in, "at_utc", false, e.at);
  ReadInto(in, "user_id", e.entry.user_id);
  ReadInto(in, "actor", e.entry.actor);
  ReadInto(in, "action", e.entry.action);
  ReadInto(in, "target", e.entry.target);
  ReadInto(in, "request_summary", e.entry.request_summary);
  ReadInto(in, "outcome", e.entry.outcome);
  return ReadResult(in, std::move(e));
}

}  // namespace fesbench::api
