#pragma once

/// @file
/// Small conversions between the transport and the application services
/// (server/services): the acting principal of an authenticated user and the
/// run-start request. The analysis requests' JSON lives with their services
/// (server/services/analysis_json.h).

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "api/run_start.h"
#include "api/status.h"
#include "server/protocols/protocol.h"
#include "server/services/actor.h"
#include "storage/users.h"

namespace fesbench::server::http {

/// The services' Actor for an authenticated user.
services::Actor ActorOf(const storage::User& user);

/// POST /sessions/{id}/runs (api/run_start.h), with the protocol looked up
/// in the catalogue (kNotFound naming "protocol") and every choice given by
/// name turned into its index (kInvalidArgument naming the parameter).
using StartRunRequest = api::StartRunRequest;
api::Result<StartRunRequest> StartRunFromJson(const nlohmann::json& body);

}  // namespace fesbench::server::http
