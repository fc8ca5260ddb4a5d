#pragma once

/// @file
/// The acting principal of every state-changing service call (docs/ARCHITECTURE.md,
/// "Audit log"): who did it and with which role. Services write it into the audit
/// log (storage::AuditLog) in the same transaction as the change.

#include <cstdint>
#include <string>

#include "api/status.h"
#include "storage/database.h"
#include "storage/users.h"

namespace fesbench::server::services {

/// What a user may do (docs/API.md, roles): clinicians run protocols on the bench,
/// analysts fit and compare models, admins do everything incl. users and the
/// simulated subject. The stored role of the user (storage/users.h), with its
/// wire names "clinician", "analyst", "admin".
using storage::ParseRole;
using storage::Role;
using storage::RoleName;

/// The acting principal. `user_id` is the storage users.id (0 for the
/// server itself, e.g. a shutdown or the heartbeat watchdog).
struct Actor {
  std::int64_t user_id = 0;
  std::string user_name;
  Role role = Role::kClinician;
};

/// The server acting on its own behalf (shutdown, watchdog): user id 0,
/// name "system", role admin.
Actor SystemActor();

/// True when `actor` may drive the bench (start/cancel runs, clear an
/// e-stop): clinicians and admins.
bool MayOperateBench(const Actor& actor);

/// Appends an audit row by `actor` (storage::AuditLog): inside a caller's
/// db.Write it joins that transaction. An actor without a name is recorded
/// as "unknown".
api::Status AppendAudit(storage::Database& db, const Actor& actor, const std::string& action,
                        const std::string& target, const std::string& summary,
                        const std::string& outcome);

}  // namespace fesbench::server::services
