// Protocols: the catalogue and one protocol, with defaults resolved from a
// session (docs/API.md, docs/PROTOCOLS.md).

#include "server/http/api_routes.h"
#include "server/http/resources_json.h"
#include "server/http/routes_common.h"
#include "server/protocols/protocol.h"
#include "server/services/run_service.h"

namespace fesbench::server::http {

using nlohmann::json;

// Protocols: the catalog and one protocol, with defaults resolved from a session.
void AddProtocolRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  // ?session_id=N resolves the defaults derived from the session.
  const auto session_context =
      [&db, runs = deps.runs](
          RequestContext& ctx) -> api::Result<std::optional<services::SessionContext>> {
    auto id = QueryId(ctx, "session_id");
    if (!id.ok()) return id.status();
    if (!*id) return std::optional<services::SessionContext>();
    auto context =
        services::LoadSessionContext(db, **id, runs ? runs->bench().limits() : BenchLimits{});
    if (!context.ok()) return context.status();
    return std::optional<services::SessionContext>(std::move(*context));
  };
  const std::vector<QueryParam> protocol_query = {
      {"session_id", "integer",
       "resolve the defaults derived from this session (threshold, max tolerated, range)"}};
  table.Add({.method = "GET",
             .path = "/api/v1/protocols",
             .permission = Permission::kRead,
             .tag = "protocols",
             .summary =
                 "The protocol catalog (docs/PROTOCOLS.md): labels, units, defaults (resolved with "
                 "?session_id), thesis sections",
             .query = protocol_query,
             .handler = [session_context](RequestContext& ctx) -> api::Result<Reply> {
               auto context = session_context(ctx);
               if (!context.ok()) return context.status();
               if (!*context) return JsonReply(protocols::CatalogToJson());
               return JsonReply(protocols::CatalogToJson(&(*context)->subject,
                                                         (*context)->has_stimulation_limits));
             }});
  table.Add({.method = "GET",
             .path = "/api/v1/protocols/{name}",
             .permission = Permission::kRead,
             .tag = "protocols",
             .summary = "One protocol with its parameters, labels, units and defaults",
             .query = protocol_query,
             .handler = [session_context](RequestContext& ctx) -> api::Result<Reply> {
               const auto* protocol = protocols::FindProtocol(ctx.path.at("name"));
               if (!protocol) {
                 return api::Status::NotFound("protocol " + ctx.path.at("name") + " not found");
               }
               auto context = session_context(ctx);
               if (!context.ok()) return context.status();
               if (!*context) return JsonReply(protocols::ProtocolToJson(*protocol));
               return JsonReply(protocols::ProtocolToJson(*protocol, &(*context)->subject,
                                                          (*context)->has_stimulation_limits));
             }});
}

}  // namespace fesbench::server::http
