#include "server/http/openapi.h"

#include <cctype>

namespace fesbench::server::http {

namespace {

using nlohmann::json;

json ErrorRef(const std::string& description) {
  return {
      {"description", description},
      {"content", {{"application/json", {{"schema", {{"$ref", "#/components/schemas/Error"}}}}}}}};
}

std::string OperationId(const Route& route) {
  std::string id;
  for (char c : route.method) id.push_back(static_cast<char>(std::tolower(c)));
  bool upper = true;
  for (char c : route.path.substr(std::string("/api/v1").size())) {
    if (c == '/' || c == '-' || c == '_' || c == '{' || c == '}' || c == '.') {
      upper = true;
      continue;
    }
    id.push_back(upper ? static_cast<char>(std::toupper(c)) : c);
    upper = false;
  }
  return id;
}

}  // namespace

json BuildOpenApi(const RouteTable& routes, const std::string& version) {
  json paths = json::object();
  for (const Route& route : routes.routes()) {
    json op = {
        {"summary", route.summary}, {"operationId", OperationId(route)}, {"tags", {route.tag}}};
    json parameters = json::array();
    std::string rest = route.path;
    for (std::size_t open = rest.find('{'); open != std::string::npos;
         open = rest.find('{', open + 1)) {
      const std::size_t close = rest.find('}', open);
      const std::string name = rest.substr(open + 1, close - open - 1);
      const bool is_id = name.size() >= 2 && name.substr(name.size() - 2) == "id";
      parameters.push_back(
          {{"name", name},
           {"in", "path"},
           {"required", true},
           {"schema", is_id ? json{{"type", "integer"}, {"minimum", 1}}
                            : json{{"type", "string"}, {"pattern", "^[A-Za-z0-9_-]{1,64}$"}}}});
    }
    for (const auto& q : route.query) {
      parameters.push_back({{"name", q.name},
                            {"in", "query"},
                            {"required", false},
                            {"description", q.description},
                            {"schema", {{"type", q.type}}}});
    }
    if (!parameters.empty()) op["parameters"] = std::move(parameters);
    if (route.json_body) {
      json schema =
          route.request_schema.is_null() ? json{{"type", "object"}} : route.request_schema;
      op["requestBody"] = {{"required", true},
                           {"content", {{"application/json", {{"schema", std::move(schema)}}}}}};
    } else if (route.raw_body) {
      // An upload: JSON (request_schema) or an archive.
      json content = {
          {"application/zip", {{"schema", {{"type", "string"}, {"format", "binary"}}}}},
          {"application/gzip", {{"schema", {{"type", "string"}, {"format", "binary"}}}}}};
      if (!route.request_schema.is_null()) {
        content["application/json"] = {{"schema", route.request_schema}};
      }
      op["requestBody"] = {{"required", true}, {"content", std::move(content)}};
    }
    json success = {{"description", "success"}};
    json success_schema =
        route.response_schema.is_null() ? json{{"type", "object"}} : route.response_schema;
    if (route.produces == "application/json") {
      success["content"] = {{"application/json", {{"schema", std::move(success_schema)}}}};
    } else {
      success["content"] = {{route.produces, {{"schema", {{"type", "string"}}}}}};
    }
    json responses = {{std::to_string(route.success_status), std::move(success)}};
    responses["400"] = ErrorRef("invalid input (field named in error.field)");
    if (route.permission) {
      responses["401"] = ErrorRef("missing, unknown, revoked or expired bearer token");
      responses["403"] = ErrorRef("role not allowed (x-roles)");
      op["security"] = json::array({{{"bearer", json::array()}}});
      json roles = json::array();
      for (storage::Role role : services::RolesIn(services::RolesFor(*route.permission))) {
        roles.push_back(storage::RoleName(role));
      }
      op["x-roles"] = std::move(roles);
    } else {
      op["security"] = json::array();
    }
    if (route.path.find('{') != std::string::npos) responses["404"] = ErrorRef("unknown id");
    responses["405"] = ErrorRef("method not allowed on this path");
    if (route.method != "GET") responses["409"] = ErrorRef("conflict with the current state");
    if (route.json_body || route.raw_body) {
      responses["413"] = ErrorRef("request body too large");
      responses["415"] = ErrorRef("Content-Type is not application/json");
    }
    responses["503"] = ErrorRef("overloaded or service unavailable; retry later");
    op["responses"] = std::move(responses);
    std::string method;
    for (char c : route.method) method.push_back(static_cast<char>(std::tolower(c)));
    paths[route.path][method] = std::move(op);
  }
  return {{"openapi", "3.0.3"},
          {"info",
           {{"title", "fesbench API"},
            {"version", version},
            {"description",
             "Functional electrical stimulation bench: subjects, sessions, protocol runs, "
             "trials, parameter sets, identification, prediction and comparison jobs "
             "(docs/API.md). Errors are {\"error\": {\"code\", \"message\", \"field\"}}."}}},
          {"servers", json::array({{{"url", "/"}}})},
          {"paths", std::move(paths)},
          {"components",
           {{"securitySchemes", {{"bearer", {{"type", "http"}, {"scheme", "bearer"}}}}},
            {"schemas",
             {{"Error",
               {{"type", "object"},
                {"required", {"error"}},
                {"properties",
                 {{"error",
                   {{"type", "object"},
                    {"required", {"code", "message"}},
                    {"properties",
                     {{"code", {{"type", "string"}}},
                      {"message", {{"type", "string"}}},
                      {"field", {{"type", "string"}}}}}}}}}}}}}}}};
}

}  // namespace fesbench::server::http
