#pragma once

/// @file
/// Small conversions between the transport and the application services
/// (server/services): the acting principal of an authenticated user and the
/// run-start request. The analysis requests' JSON lives with their services
/// (server/services/analysis_json.h).

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "api/status.h"
#include "server/protocols/protocol.h"
#include "server/services/actor.h"
#include "storage/users.h"

namespace fesbench::server::http {

/// The services' Actor for an authenticated user.
services::Actor ActorOf(const storage::User& user);

/// POST /sessions/{id}/runs: {"protocol": "<name>", "parameters"?: {"<name>": number},
/// "ceiling_reason"?: "<why a tolerance test goes above the recorded max>"}.
/// "target_samples"?: {"t_s": [...], "angle_deg": [...]} (tracking's uploaded
/// target, at most kMaxTargetSamples samples).
struct StartRunRequest {
  std::string protocol;
  protocols::ParameterValues parameters;
  std::optional<std::string> ceiling_reason;
  std::optional<protocols::TargetSamples> target;
};
inline constexpr std::size_t kMaxTargetSamples = 40000;
api::Result<StartRunRequest> StartRunFromJson(const nlohmann::json& body);

}  // namespace fesbench::server::http
