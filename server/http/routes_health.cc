// GET /health (docs/API.md).

#include "server/http/api_routes.h"
#include "server/http/resources_json.h"
#include "server/http/routes_common.h"

namespace fesbench::server::http {

using nlohmann::json;

// GET /health: liveness, version, schema version.
void AddHealthRoute(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  const std::string version = deps.server_version;
  table.Add({.method = "GET",
             .path = "/api/v1/health",
             .permission = std::nullopt,
             .tag = "system",
             .summary = "Liveness and database health",
             .handler = [&db, version](RequestContext&) -> api::Result<Reply> {
               auto schema = db.SchemaVersion();
               if (!schema.ok()) return schema.status();
               return JsonReply({{"status", "ok"},
                                 {"version", version},
                                 {"schema_version", *schema},
                                 {"time_utc", api::FormatUtc(db.Now())}});
             }});
}

}  // namespace fesbench::server::http
