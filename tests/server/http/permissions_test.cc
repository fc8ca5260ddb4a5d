// The one table of who may do what (docs/API.md, "Roles and permissions";
// docs/ARCHITECTURE.md, "Role checks in one place"): docs/API.md's table of
// permissions is services::RolesFor's, every route's permission and roles in
// docs/API.md's resource table are the route table's (and its OpenAPI
// x-roles), and a refusal reads as each transport's did.

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include "server/http/api_routes.h"
#include "server/http/openapi.h"
#include "server/services/actor.h"

namespace fesbench::server::http {
namespace {

using nlohmann::json;
using services::RoleMask;

std::vector<std::string> ApiMdLines() {
  std::ifstream in(std::string(FESBENCH_SOURCE_DIR) + "/docs/API.md");
  EXPECT_TRUE(in.good()) << "docs/API.md not found";
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// The cells of a Markdown table row ("| a | b |", maybe indented), trimmed;
// an escaped "\|" stays inside its cell.
std::vector<std::string> Cells(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  const std::size_t start = line.find('|');
  if (start == std::string::npos) return cells;
  for (std::size_t i = start + 1; i < line.size(); ++i) {
    if (line[i] == '\\' && i + 1 < line.size() && line[i + 1] == '|') {
      cell += "\\|";
      ++i;
    } else if (line[i] == '|') {
      const std::size_t b = cell.find_first_not_of(' ');
      const std::size_t e = cell.find_last_not_of(' ');
      cells.push_back(b == std::string::npos ? "" : cell.substr(b, e - b + 1));
      cell.clear();
    } else {
      cell += line[i];
    }
  }
  return cells;
}

// The rows of the table whose header row is `header` (its first cells), the
// separator row skipped.
std::vector<std::vector<std::string>> TableRows(const std::vector<std::string>& header) {
  const std::vector<std::string> lines = ApiMdLines();
  std::vector<std::vector<std::string>> rows;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    std::vector<std::string> cells = Cells(lines[i]);
    if (cells.size() < header.size() || !std::equal(header.begin(), header.end(), cells.begin())) {
      continue;
    }
    for (std::size_t j = i + 2; j < lines.size(); ++j) {
      std::vector<std::string> row = Cells(lines[j]);
      if (row.empty()) break;
      rows.push_back(std::move(row));
    }
    break;
  }
  EXPECT_FALSE(rows.empty()) << "docs/API.md has no table headed " << header[0];
  return rows;
}

// A roles cell: "any", "clinician, admin", …; 0 for "open".
RoleMask MaskOf(const std::string& cell) {
  if (cell == "any") return services::kAnyRole;
  RoleMask mask = 0;
  for (services::Role role :
       {services::Role::kClinician, services::Role::kAnalyst, services::Role::kAdmin}) {
    if (cell.find(services::RoleName(role)) != std::string::npos) mask |= services::RoleBit(role);
  }
  return mask;
}

// "METHOD /api/v1/a/{}/b": a route with its path parameters unnamed, as
// docs/API.md names them differently ({id}) and leaves out /api/v1.
std::string RouteKey(const std::string& method, std::string path) {
  if (!path.starts_with("/api/v1")) path = "/api/v1" + path;
  path = path.substr(0, path.find('?'));
  return method + " " + std::regex_replace(path, std::regex(R"(\{[^}]*\})"), "{}");
}

TEST(PermissionsTest, DocsApiTableIsTheServersTable) {
  std::map<std::string, RoleMask> documented;
  for (const auto& row : TableRows({"permission", "roles", "allows"})) {
    ASSERT_GE(row.size(), 3u);
    ASSERT_TRUE(row[0].size() > 2 && row[0].front() == '`' && row[0].back() == '`') << row[0];
    const std::string name = row[0].substr(1, row[0].size() - 2);
    EXPECT_FALSE(documented.contains(name)) << name << " twice";
    documented[name] = MaskOf(row[1]);
    EXPECT_NE(documented[name], 0u) << name << ": no role in '" << row[1] << "'";
  }
  std::set<std::string> served;
  for (Permission permission : services::AllPermissions()) {
    const std::string name(services::PermissionName(permission));
    served.insert(name);
    const auto it = documented.find(name);
    if (it == documented.end()) {
      ADD_FAILURE() << "docs/API.md does not list the permission " << name;
      continue;
    }
    EXPECT_EQ(it->second, services::RolesFor(permission))
        << name << ": docs/API.md says " << services::RoleList(it->second) << ", the server "
        << services::RoleList(services::RolesFor(permission));
  }
  for (const auto& [name, mask] : documented) {
    EXPECT_TRUE(served.contains(name))
        << "docs/API.md lists " << name << ", which the server lacks";
  }
  EXPECT_EQ(served.size(), 8u);
}

struct RouteRig {
  RouteRig() {
    static std::atomic<int> counter{0};
    dir = std::filesystem::temp_directory_path() /
          ("fesbench_permissions_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    std::filesystem::create_directories(dir);
    storage::DatabaseOptions o;
    o.path = (dir / "fesbench.db").string();
    o.synchronous = storage::Synchronous::kNormal;
    db = std::move(storage::Database::Open(o)).value();
    auth = std::make_unique<Authenticator>(*db);
    ApiDependencies deps;
    deps.db = db.get();
    deps.auth = auth.get();
    deps.streams = &streams;
    deps.backup_dir = (dir / "backups").string();
    table = BuildApiRoutes(deps);
  }
  ~RouteRig() {
    table = RouteTable();
    auth.reset();
    db.reset();
    std::filesystem::remove_all(dir);
  }
  std::filesystem::path dir;
  std::unique_ptr<storage::Database> db;
  std::unique_ptr<Authenticator> auth;
  StreamSlots streams{4};
  RouteTable table;
};

// Every route: the permission docs/API.md names for it, the roles column is
// that permission's roles, and so is the OpenAPI document's x-roles.
TEST(PermissionsTest, EveryRoutesRolesAreItsPermissionsAsDocumented) {
  struct Documented {
    RoleMask roles = 0;
    std::string permission;
  };
  std::map<std::string, Documented> documented;
  const std::regex route("`([A-Z]+) (/[^`]*)`");
  for (const auto& row : TableRows({"method and path", "roles", "permission"})) {
    ASSERT_GE(row.size(), 4u);
    const std::string permission =
        row[2] == "—" ? std::string("open") : row[2].substr(1, row[2].size() - 2);
    const RoleMask roles = row[1] == "open" ? 0 : MaskOf(row[1]);
    for (std::sregex_iterator it(row[0].begin(), row[0].end(), route), end; it != end; ++it) {
      documented[RouteKey((*it)[1], (*it)[2])] = {roles, permission};
    }
  }

  RouteRig rig;
  const json doc = BuildOpenApi(rig.table, "test");
  std::set<std::string> served;
  std::size_t open = 0;
  for (const Route& r : rig.table.routes()) {
    const std::string key = RouteKey(r.method, r.path);
    SCOPED_TRACE(key);
    served.insert(key);
    const RoleMask roles = r.permission ? services::RolesFor(*r.permission) : 0;
    const std::string name =
        r.permission ? std::string(services::PermissionName(*r.permission)) : "open";
    if (!r.permission) ++open;
    const auto it = documented.find(key);
    if (it == documented.end()) {
      ADD_FAILURE() << "docs/API.md does not list the route";
      continue;
    }
    EXPECT_EQ(it->second.permission, name);
    EXPECT_EQ(it->second.roles, roles) << "docs/API.md: " << services::RoleList(it->second.roles)
                                       << "; the permission's: " << services::RoleList(roles);

    std::string lower = r.method;
    for (char& c : lower) c = static_cast<char>(std::tolower(c));
    const json& op = doc["paths"][r.path][lower];
    json x_roles = json::array();
    for (services::Role role : services::RolesIn(roles)) {
      x_roles.push_back(services::RoleName(role));
    }
    if (r.permission) {
      EXPECT_EQ(op["x-roles"], x_roles);
    } else {
      EXPECT_FALSE(op.contains("x-roles"));
      EXPECT_EQ(op["security"], json::array());
    }
  }
  EXPECT_EQ(open, 2u) << "health and openapi.json only";
  for (const auto& [key, row] : documented) {
    EXPECT_TRUE(served.contains(key)) << "docs/API.md lists " << key << ", which is not served";
  }
}

services::Actor ActorWith(services::Role role) {
  return services::Actor{7, std::string(services::RoleName(role)) + "_user", role};
}

TEST(PermissionsTest, RequireAllowsExactlyThePermissionsRoles) {
  for (Permission permission : services::AllPermissions()) {
    for (services::Role role :
         {services::Role::kClinician, services::Role::kAnalyst, services::Role::kAdmin}) {
      SCOPED_TRACE(std::string(services::PermissionName(permission)) + " " +
                   std::string(services::RoleName(role)));
      const bool allowed = (services::RolesFor(permission) & services::RoleBit(role)) != 0;
      const services::Actor actor = ActorWith(role);
      EXPECT_EQ(services::May(actor, permission), allowed);
      EXPECT_EQ(services::Require(actor, permission).ok(), allowed);
      EXPECT_EQ(services::Require(actor, permission, "it").ok(), allowed);
      if (!allowed) {
        EXPECT_EQ(services::Require(actor, permission).code(), api::ErrorCode::kPermissionDenied);
      }
    }
    // Admins may do everything.
    EXPECT_TRUE(services::May(ActorWith(services::Role::kAdmin), permission));
  }
}

// The front ends' message (HTTP 403, DDS reply) and a service's own, as
// they read before the table.
TEST(PermissionsTest, RefusalsReadAsBefore) {
  const services::Actor analyst = ActorWith(services::Role::kAnalyst);
  const services::Actor clinician = ActorWith(services::Role::kClinician);
  EXPECT_EQ(services::Require(analyst, Permission::kOperateBench).message(),
            "role analyst may not do this (allowed: clinician, admin)");
  EXPECT_EQ(services::Require(clinician, Permission::kAnalyse).message(),
            "role clinician may not do this (allowed: analyst, admin)");
  EXPECT_EQ(services::Require(analyst, Permission::kAdminister).message(),
            "role analyst may not do this (allowed: admin)");
  EXPECT_EQ(services::Require(analyst, Permission::kOperateBench, "starting a run").message(),
            "starting a run needs the clinician or admin role");
  EXPECT_EQ(services::Require(clinician, Permission::kAnalyse, "fitting parameter sets").message(),
            "fitting parameter sets needs the analyst or admin role");
  EXPECT_EQ(services::Require(clinician, Permission::kAdminister, "reading the virtual subject")
                .message(),
            "reading the virtual subject needs the admin role");
  EXPECT_EQ(services::RoleList(services::kAnyRole), "clinician, analyst, admin");
}

}  // namespace
}  // namespace fesbench::server::http
