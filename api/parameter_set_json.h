#pragma once

/// @file
/// JSON wire form of the parameter set (docs/MODEL.md, "The parameter set"). Every key names its
/// unit. Reading validates everything and reports the first bad field by its
/// dotted path (e.g. "passive.torque_angle.angle_deg").

#include <nlohmann/json.hpp>

#include "api/status.h"
#include "model/parameter_set.h"

namespace fesbench::api {

/// The JSON form of a parameter set. Never fails.
nlohmann::json ParameterSetToJson(const model::ParameterSet& params);

/// Parses and validates a parameter set. Rejects (kInvalidArgument, with the
/// field path): unknown model name, missing or wrongly typed fields, NaN or
/// infinite numbers, breakpoints not strictly increasing, mismatched array
/// lengths, a non-positive inertia or pole, negative gains or torque scale,
/// a contraction order other than 2 or 3, an IRC outside [0, 1].
Result<model::ParameterSet> ParameterSetFromJson(const nlohmann::json& json);

}  // namespace fesbench::api
