#include "server/services/actor.h"

#include <array>

#include "storage/audit_log.h"

namespace fesbench::server::services {
namespace {

struct PermissionRow {
  Permission permission;
  std::string_view name;
  RoleMask roles;
};

// Who may do what (docs/API.md, "Roles and permissions"): the one table.
constexpr std::array<PermissionRow, 8> kPermissionTable{{
    {Permission::kRead, "read", kAnyRole},
    {Permission::kEStop, "estop", kAnyRole},
    {Permission::kPredict, "predict", kAnyRole},
    {Permission::kRecord, "record", kClinician | kAdmin},
    {Permission::kApprove, "approve", kClinician | kAdmin},
    {Permission::kOperateBench, "operate_bench", kClinician | kAdmin},
    {Permission::kAnalyse, "analyse", kAnalyst | kAdmin},
    {Permission::kAdminister, "administer", kAdmin},
}};

// In the enum's order, each once, to its last value: RowOf indexes the table.
static_assert([] {
  for (std::size_t i = 0; i < kPermissionTable.size(); ++i) {
    if (kPermissionTable[i].permission != static_cast<Permission>(i)) return false;
  }
  return kPermissionTable.back().permission == Permission::kAdminister;
}());

constexpr std::array<Permission, kPermissionTable.size()> kPermissions = [] {
  std::array<Permission, kPermissionTable.size()> out{};
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = kPermissionTable[i].permission;
  return out;
}();

// The static_assert above makes a permission its row's index.
constexpr const PermissionRow& RowOf(Permission permission) {
  return kPermissionTable[static_cast<std::size_t>(permission)];
}

// The roles of `mask` in the order clinician, analyst, admin, the last one
// after `last_separator`: "clinician, admin", "clinician, analyst or admin".
std::string JoinRoles(RoleMask mask, std::string_view last_separator) {
  const std::vector<Role> roles = RolesIn(mask);
  std::string out;
  for (std::size_t i = 0; i < roles.size(); ++i) {
    if (i > 0) out += i + 1 == roles.size() ? last_separator : std::string_view(", ");
    out += RoleName(roles[i]);
  }
  return out;
}

}  // namespace

Actor SystemActor() { return Actor{0, "system", Role::kAdmin}; }

std::vector<Role> RolesIn(RoleMask mask) {
  std::vector<Role> roles;
  for (Role role : {Role::kClinician, Role::kAnalyst, Role::kAdmin}) {
    if (mask & RoleBit(role)) roles.push_back(role);
  }
  return roles;
}

std::string RoleList(RoleMask mask) { return JoinRoles(mask, ", "); }

std::span<const Permission> AllPermissions() { return kPermissions; }

RoleMask RolesFor(Permission permission) { return RowOf(permission).roles; }

std::string_view PermissionName(Permission permission) { return RowOf(permission).name; }

bool May(const Actor& actor, Permission permission) {
  return (RolesFor(permission) & RoleBit(actor.role)) != 0;
}

api::Status Require(const Actor& actor, Permission permission) {
  if (May(actor, permission)) return api::Status::Ok();
  return {api::ErrorCode::kPermissionDenied,
          "role " + std::string(RoleName(actor.role)) +
              " may not do this (allowed: " + RoleList(RolesFor(permission)) + ")"};
}

api::Status Require(const Actor& actor, Permission permission, std::string_view what) {
  if (May(actor, permission)) return api::Status::Ok();
  return {api::ErrorCode::kPermissionDenied,
          std::string(what) + " needs the " + JoinRoles(RolesFor(permission), " or ") + " role"};
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
