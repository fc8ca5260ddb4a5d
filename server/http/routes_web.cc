// Routes the web client needs beside the resources (docs/API.md): who is
// signed in, so the page can show the user's name and role.

#include "server/http/api_routes.h"
#include "server/http/routes_common.h"

namespace fesbench::server::http {

void AddWebRoutes(RouteTable& table, const ApiDependencies&) {
  table.Add(
      {.method = "GET",
       .path = "/api/v1/me",
       .permission = Permission::kRead,
       .tag = "users",
       .summary = "The signed-in user (id, name, role) of the bearer token",
       .response_schema = ObjectSchema({{"id", {{"type", "integer"}}},
                                        {"name", {{"type", "string"}}},
                                        {"role", {{"enum", {"clinician", "analyst", "admin"}}}}},
                                       {"id", "name", "role"}),
       .handler = [](RequestContext& ctx) -> api::Result<Reply> {
         const storage::User& user = *ctx.user;
         return JsonReply(api::SignedInUserToJson(user));
       }});
}

}  // namespace fesbench::server::http
