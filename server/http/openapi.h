#pragma once

/// @file
/// The OpenAPI 3.0 document of the API, built from the route table the
/// server dispatches from (router.h), so every route is documented and
/// every documented route exists.

#include <nlohmann/json.hpp>
#include <string>

#include "server/http/router.h"

namespace fesbench::server::http {

/// {"openapi": "3.0.3", "info", "paths", "components": {"schemas": {"Error"},
/// "securitySchemes": {"bearer"}}}. Each operation lists its path and query
/// parameters, request body schema, success response and the error
/// responses it can give (400/401/403/404/405/409/413/415/503 as
/// applicable), and "x-roles" (the roles allowed; absent when open).
nlohmann::json BuildOpenApi(const RouteTable& routes, const std::string& version);

}  // namespace fesbench::server::http
