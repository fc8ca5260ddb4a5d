#include "server/http/api_routes.h"

#include <memory>

#include "server/http/openapi.h"
#include "server/http/routes_common.h"

namespace fesbench::server::http {

RouteTable BuildApiRoutes(const ApiDependencies& deps) {
  RouteTable table;
  auto document = std::make_shared<std::string>();
  table.Add({.method = "GET",
             .path = "/api/v1/openapi.json",
             .permission = std::nullopt,
             .tag = "system",
             .summary = "This OpenAPI 3 document (built from the server's route table)",
             .handler = [document](RequestContext& ctx) -> api::Result<Reply> {
               ctx.res.status = 200;
               ctx.res.set_content(*document, "application/json");
               return Reply{200, nullptr, true};
             }});
  AddHealthRoute(table, deps);
  AddSubjectRoutes(table, deps);
  AddSessionRoutes(table, deps);
  AddTrialRoutes(table, deps);
  AddParameterSetRoutes(table, deps);
  AddProtocolRoutes(table, deps);
  AddAdminRoutes(table, deps);
  AddBenchRoutes(table, deps);
  AddJobRoutes(table, deps);
  AddDataRoutes(table, deps);
  AddApprovalRoutes(table, deps);
  AddWebRoutes(table, deps);
  *document = BuildOpenApi(table, deps.server_version).dump();
  return table;
}

}  // namespace fesbench::server::http
