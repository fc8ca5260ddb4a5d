#pragma once

/// @file
/// The acting principal of every state-changing service call (docs/ARCHITECTURE.md,
/// "Audit log"): who did it and with which role. Services write it into the audit
/// log (storage::AuditLog) in the same transaction as the change.
///
/// Who may do what is one table of permissions (docs/API.md, "Roles and
/// permissions"; docs/ARCHITECTURE.md, "Role checks in one place"): every HTTP route
/// declares the permission it needs (server/http/router.h, Route::permission),
/// and every service that a DDS command reaches without the route table checks
/// the same permission with Require.

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "api/status.h"
#include "storage/database.h"
#include "storage/users.h"

namespace fesbench::server::services {

/// The stored role of the user (storage/users.h), with its wire names
/// "clinician", "analyst", "admin": clinicians run protocols on the bench,
/// analysts fit and compare models, admins do everything incl. users and the
/// simulated subject. What each may do is the table of permissions below.
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

/// A set of roles as bits (RoleBit).
using RoleMask = unsigned;
constexpr RoleMask RoleBit(Role role) { return 1u << static_cast<unsigned>(role); }
inline constexpr RoleMask kClinician = RoleBit(Role::kClinician);
inline constexpr RoleMask kAnalyst = RoleBit(Role::kAnalyst);
inline constexpr RoleMask kAdmin = RoleBit(Role::kAdmin);
inline constexpr RoleMask kAnyRole = kClinician | kAnalyst | kAdmin;

/// The roles of `mask`, in the order clinician, analyst, admin.
std::vector<Role> RolesIn(RoleMask mask);
/// "clinician, admin": the roles of `mask`, in that order.
std::string RoleList(RoleMask mask);

/// What a signed-in user may do, named by what it allows. Which roles hold
/// each is one table (RolesFor, in actor.cc; docs/API.md, "Roles and
/// permissions"); several may share roles and still differ in what they mean.
enum class Permission {
  kRead,          ///< read every resource, follow runs and new parameter sets live.
  kEStop,         ///< press the e-stop.
  kPredict,       ///< submit predictions and model checks, follow a job.
  kRecord,        ///< create and correct subjects and sessions, import trials.
  kApprove,       ///< approve a parameter set for its leg (also by the run that made it).
  kOperateBench,  ///< start, stop, cancel and heart-beat runs, clear the e-stop.
  kAnalyse,       ///< submit identifications and comparisons, list the jobs.
  kAdminister,    ///< users, tokens, the audit log, backups, the virtual subject (the last).
};

/// Every permission, in the table's order.
std::span<const Permission> AllPermissions();
/// The roles that have `permission`.
RoleMask RolesFor(Permission permission);
/// Its name in docs/API.md: "read", "estop", "operate_bench", …
std::string_view PermissionName(Permission permission);

/// True when `actor`'s role has `permission`.
bool May(const Actor& actor, Permission permission);
/// Ok when `actor` may; otherwise kPermissionDenied with the front ends'
/// message, "role analyst may not do this (allowed: clinician, admin)" (an
/// HTTP route's 403, a DDS command's refusal).
api::Status Require(const Actor& actor, Permission permission);
/// Ok when `actor` may; otherwise kPermissionDenied with a service's message
/// naming what was refused: "<what> needs the clinician or admin role".
api::Status Require(const Actor& actor, Permission permission, std::string_view what);

/// Appends an audit row by `actor` (storage::AuditLog): inside a caller's
/// db.Write it joins that transaction. An actor without a name is recorded
/// as "unknown".
api::Status AppendAudit(storage::Database& db, const Actor& actor, const std::string& action,
                        const std::string& target, const std::string& summary,
                        const std::string& outcome);

}  // namespace fesbench::server::services
