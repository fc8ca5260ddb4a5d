#pragma once

/// @file
/// The request that starts a run (docs/API.md, "Runs": POST /sessions/{id}/runs),
/// for the server that reads it and the clients that send it:
///   {"protocol": "<name>", "parameters"?: {"<name>": number | "<choice>"},
///    "ceiling_reason"?: "<why a tolerance test goes above the recorded max>",
///    "target_samples"?: {"t_s": [...], "angle_deg": [...]}}
/// Reading checks the form (types, lengths, unknown fields) and names the
/// field; whether the protocol exists, a choice is one of its names and the
/// values are in range is the server's catalogue to decide.

#include <cstddef>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "api/run.h"
#include "api/status.h"

namespace fesbench::api {

/// A tracking run's uploaded target trajectory: strictly increasing t_s, deg.
struct TargetSamples {
  std::vector<double> t_s = {};
  std::vector<double> angle_deg = {};
};

/// Most samples an uploaded target may have (200 s at 200 Hz).
inline constexpr std::size_t kMaxTargetSamples = 40000;
/// Most parameters a request may name.
inline constexpr std::size_t kMaxRunParameters = 64;

struct StartRunRequest {
  std::string protocol = {};
  ParameterValues parameters = {};  ///< numbers, in each parameter's unit.
  /// Choice parameters given by name ("target": "uploaded"); the server
  /// turns each into its index among the protocol's choices.
  std::map<std::string, std::string, std::less<>> choices = {};
  std::optional<std::string> ceiling_reason = std::nullopt;
  std::optional<TargetSamples> target = std::nullopt;
};

Result<StartRunRequest> StartRunRequestFromJson(const nlohmann::json& json);
nlohmann::json StartRunRequestToJson(const StartRunRequest& request);

}  // namespace fesbench::api
