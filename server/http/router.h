#pragma once

/// @file
/// The route table: every route of the API as data (method, path template,
/// permission, body, query parameters, summary, handler). The server dispatches
/// from it and the OpenAPI document is built from it (openapi.h), so the
/// two cannot drift apart.
///
/// Path templates use `{name}` segments; a name ending in `id` matches a
/// positive decimal integer (at most 18 digits), any other name matches
/// 1–64 characters of [A-Za-z0-9_-]. Matching is per segment, exact
/// otherwise; no route matches a path with "..", empty or encoded-slash
/// segments.

#include "server/http/message.h"

#include <cstdint>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/status.h"
#include "server/http/auth.h"
#include "storage/users.h"

namespace fesbench::server::http {

/// An upload's body (routes with `raw_body` whose requests are uploads,
/// request_framing.h IsUpload): the front end spools it to an unlinked
/// temporary file as it arrives instead of holding it in memory, so a
/// handler reads it from `fd` (a regular file, positioned at 0, open for the
/// request only) and `req.body` is empty.
struct UploadBody {
  int fd = -1;
  std::size_t size = 0;  ///< bytes in the file: the request's Content-Length.
};

/// What a handler sees.
struct RequestContext {
  const Request& req;
  Response& res;
  std::map<std::string, std::string, std::less<>> path;  ///< template name → segment.
  std::optional<storage::User> user;                     ///< set on authenticated routes.
  nlohmann::json body;                                   ///< parsed JSON body (body routes).
  /// Set for uploads (UploadBody); nullptr otherwise.
  const UploadBody* upload = nullptr;

  /// The integer path parameter `name` (the template guarantees digits).
  std::int64_t Id(std::string_view name) const;
  /// A query parameter, if present.
  std::optional<std::string> Query(const std::string& name) const;
};

/// A handler's answer: a JSON body with a status, or `raw` when the handler
/// filled `res` itself (CSV, event streams).
struct Reply {
  int status = 200;
  nlohmann::json body;
  bool raw = false;
};

using Handler = std::function<api::Result<Reply>(RequestContext&)>;

/// Who writes the audit entry of a state-changing request (POST, PUT, PATCH,
/// DELETE) by a signed-in user (docs/API.md, "HTTP conventions"). Whatever
/// the route says, a refused request (an error answer) is audited by the
/// dispatcher, unless the route is kNever.
enum class Audit {
  kDispatcher,  ///< the dispatcher, once the handler has succeeded.
  kHandler,     ///< the handler, in the transaction of its change (AuditedWrite,
                ///< AuditedCorrection, or the service it calls).
  kNever,       ///< nobody: the request changes nothing (a heartbeat).
};

/// A query parameter, for validation and the OpenAPI document.
struct QueryParam {
  std::string name;
  std::string type;  ///< "integer", "string".
  std::string description;
};

struct Route {
  std::string method;      ///< "GET", "POST", "PUT", "DELETE".
  std::string path;        ///< "/api/v1/subjects/{subject_id}".
  /// What the caller needs (services::RolesFor gives its roles); nullopt: the
  /// route is open (no token needed).
  std::optional<Permission> permission;
  Audit audit = Audit::kDispatcher;
  bool json_body = false;  ///< requires an application/json object body.
  std::string tag;         ///< OpenAPI tag.
  std::string summary = {};
  std::vector<QueryParam> query = {};
  int success_status = 200;
  std::string produces = "application/json";  ///< or "text/event-stream", …
  nlohmann::json request_schema = nullptr;    ///< JSON Schema of the body (null: generic object).
  nlohmann::json response_schema = nullptr;   ///< JSON Schema of the success body (null: object).
  Handler handler;
  /// The handler reads the request body itself (uploads of any media type);
  /// otherwise a body on a route without json_body is refused.
  bool raw_body = false;
};

/// The result of matching a method and path.
struct RouteMatch {
  const Route* route = nullptr;  ///< nullptr: no route for this method.
  std::map<std::string, std::string, std::less<>> path;
  std::vector<std::string> allowed_methods;  ///< methods the path has (for 405).
};

class RouteTable {
 public:
  /// Adds a route. Precondition (assert): no duplicate method + template.
  void Add(Route route);
  /// Matches `method` and `path` (a decoded request path).
  RouteMatch Match(std::string_view method, std::string_view path) const;
  const std::vector<Route>& routes() const { return routes_; }

 private:
  struct Compiled {
    std::vector<std::string> segments;
  };
  std::vector<Route> routes_;
  std::vector<Compiled> compiled_;
};

/// Splits "/a/b/c" into {"a","b","c"}; nullopt for an empty or ".."/"."
/// segment, or a path not starting with '/'.
std::optional<std::vector<std::string_view>> SplitPath(std::string_view path);

}  // namespace fesbench::server::http
