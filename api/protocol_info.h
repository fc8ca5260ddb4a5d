#pragma once

/// @file
/// A protocol as the server lists it (docs/PROTOCOLS.md; docs/API.md; GET
/// /protocols, GET /protocols/{name}): its identity, what it does with the
/// bench, and each parameter with its unit, default (resolved for a session
/// when one is given), limits and how the default follows the subject. One
/// definition for the server that describes its catalogue
/// (server/protocols/protocol.h) and the clients that show it.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "api/status.h"

namespace fesbench::api {

struct ProtocolParameterInfo {
  std::string name = {};  ///< ends in its unit (`_ma`, `_s`, `_deg`, …).
  std::string label = {};
  std::string unit = {};  ///< "mA", "s", "deg", …; "1" for counts and fractions.
  std::string description = {};
  /// The default in the parameter's unit; nullopt when it follows the
  /// subject and no session (or one without stimulation limits) was given.
  std::optional<double> default_value = std::nullopt;
  /// How a subject-scaled default is found ("the session's threshold");
  /// nullopt for a fixed default.
  std::optional<std::string> default_rule = std::nullopt;
  double min = 0.0;  ///< inclusive.
  double max = 0.0;  ///< inclusive.
  bool integer = false;
  bool advanced = false;                  ///< hidden behind "advanced" in the web client.
  std::string scales_to = "none";         ///< "none", "threshold", "max_tolerated", ….
  bool rest = false;                      ///< a rest period (not below the protocol's min_rest_s).
  std::vector<std::string> choices = {};  ///< a choice: the value is the index.
};

struct ProtocolInfo {
  std::string name = {};
  int version = 1;
  std::string title = {};
  std::string description = {};
  std::string thesis_section = {};  ///< "§5.3.1", "Appendix F", ….
  bool stimulates = true;
  std::string bench_mode = {};  ///< "locked", "motor", "decoupled", "mixed".
  double min_rest_s = 0.0;
  /// The protocol measures the subject's max tolerated amplitude (the
  /// tolerance test): it may run before a session has recorded limits, the
  /// subject's stop records the result, a cancel records nothing, and a
  /// ceiling above the recorded max takes an audited ceiling_reason.
  bool measures_max_tolerated = false;
  /// The run follows a target knee angle (tracking): its live view draws the
  /// target, and the target may be uploaded as the start request's
  /// target_samples.
  bool follows_target = false;
  /// The protocol a session with recorded limits offers first.
  bool offered_first = false;
  std::vector<ProtocolParameterInfo> parameters = {};
};

/// {"name", "version", "title", "description", "thesis_section",
///  "stimulates", "bench_mode", "min_rest_s", "measures_max_tolerated",
///  "follows_target", "offered_first", "parameters": [{"name",
///  "label", "unit", "description", "default" (null when unresolved),
///  "default_rule" (null when fixed), "min", "max", "integer", "advanced",
///  "scales_to", "rest", "choices"}]}.
nlohmann::json ProtocolInfoToJson(const ProtocolInfo& protocol);
/// kInvalidArgument naming the field ("parameters[2].max") for a field of
/// the wrong type or a missing name; fields it does not know are ignored.
Result<ProtocolInfo> ProtocolInfoFromJson(const nlohmann::json& json);

/// The catalogue (GET /protocols): {"protocols": [ProtocolInfoToJson, …]}.
nlohmann::json ProtocolCatalogueToJson(const std::vector<ProtocolInfo>& protocols);
/// Each protocol by ProtocolInfoFromJson, its failure named
/// "protocols[i].…"; a missing list is kInvalidArgument.
Result<std::vector<ProtocolInfo>> ProtocolCatalogueFromJson(const nlohmann::json& json);

}  // namespace fesbench::api
