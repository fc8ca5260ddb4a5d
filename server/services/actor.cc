#include "server/services/actor.h"

#include "storage/audit_log.h"

namespace fesbench::server::services {

Actor SystemActor() { return Actor{0, "system", Role::kAdmin}; }

bool MayOperateBench(const Actor& actor) {
  return actor.role == Role::kClinician || actor.role == Role::kAdmin;
}

api::Status AppendAudit(storage::Database& db, const Actor& actor, const std::string& action,
                        const std::string& target, const std::string& summary,
                        const std::string& outcome) {
  storage::NewAuditEntry e;
  if (actor.user_id > 0) e.user_id = actor.user_id;
  e.actor = actor.user_name.empty() ? std::string("unknown") : actor.user_name;
  e.action = action;
  e.target = target;
  e.request_summary = summary;
  e.outcome = outcome;
  api::Result<std::int64_t> id = storage::AuditLog(db).Append(e);
  return id.ok() ? api::Status::Ok() : id.status();
}

}  // namespace fesbench::server::services
