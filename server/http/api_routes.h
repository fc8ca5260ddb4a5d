#pragma once

/// @file
/// The API's routes (docs/API.md, "Resources") over storage and the application
/// services. Each route declares the permission it needs (Route::permission);
/// who has which is services::RolesFor's table (docs/API.md, "Roles and
/// permissions"). Open: health and openapi.json only.

#include <memory>
#include <string>

#include "server/http/auth.h"
#include "server/http/router.h"
#include "server/http/stream_slots.h"
#include "storage/database.h"

namespace fesbench::server::services {
class BenchService;
class RunService;
class SampleHub;
class JobPool;
class IdentificationService;
class PredictionService;
class ComparisonService;
}  // namespace fesbench::server::services

namespace fesbench::server::http {

/// What the routes call. Storage, authenticator and stream slots are
/// required; absent services make their routes answer 503 "not available".
struct ApiDependencies {
  storage::Database* db = nullptr;
  Authenticator* auth = nullptr;
  StreamSlots* streams = nullptr;
  std::string backup_dir;  ///< where POST /backup writes (created on demand).
  std::string server_version = "0.1.0";

  services::BenchService* bench = nullptr;
  services::RunService* runs = nullptr;
  services::SampleHub* samples = nullptr;
  services::JobPool* jobs = nullptr;
  services::IdentificationService* identification = nullptr;
  services::PredictionService* prediction = nullptr;
  services::ComparisonService* comparison = nullptr;
};

/// Every route, GET /api/v1/openapi.json included (built from this table).
RouteTable BuildApiRoutes(const ApiDependencies& deps);

/// Adds the routes of one area (used by BuildApiRoutes).
void AddHealthRoute(RouteTable& table, const ApiDependencies& deps);
void AddSubjectRoutes(RouteTable& table, const ApiDependencies& deps);
/// Sessions, their corrections and revisions, their runs and trials.
void AddSessionRoutes(RouteTable& table, const ApiDependencies& deps);
void AddTrialRoutes(RouteTable& table, const ApiDependencies& deps);
/// Parameter sets, their stored predictions and export.
void AddParameterSetRoutes(RouteTable& table, const ApiDependencies& deps);
void AddProtocolRoutes(RouteTable& table, const ApiDependencies& deps);
void AddAdminRoutes(RouteTable& table, const ApiDependencies& deps);
void AddBenchRoutes(RouteTable& table, const ApiDependencies& deps);
void AddJobRoutes(RouteTable& table, const ApiDependencies& deps);
/// Approving parameter sets, a leg's approved set (routes_approvals.cc).
void AddApprovalRoutes(RouteTable& table, const ApiDependencies& deps);
/// Trial import and session export (routes_data.cc).
void AddDataRoutes(RouteTable& table, const ApiDependencies& deps);
/// GET /api/v1/me (routes_web.cc): the signed-in user, for the web client.
void AddWebRoutes(RouteTable& table, const ApiDependencies& deps);

}  // namespace fesbench::server::http
