#pragma once

/// @file
/// JSON form of a virtual subject (docs/ARCHITECTURE.md, "The benches"):
/// ```json
/// {"name": "virtual-7", "seed": 7,
///  "truth": {<parameter set, docs/MODEL.md>},
///  "threshold_ma": 18.2, "max_tolerated_ma": 41.0,
///  "anthropometrics": {"body_mass_kg": 70, "height_m": 1.75, "shank_length_m": 0.43,
///                      "accel_distance_m": 0.28, "thigh_elevation_deg": 9},
///  "fidelity": {"twitch_variation": 0.3, "series_stiffness_nm_per_deg": 35, ...}}
/// ```
/// `truth`, `threshold_ma` and `max_tolerated_ma` are required; `name`,
/// `seed`, `anthropometrics`, `fidelity` and each field inside the last two
/// are optional and default to the values in virtual_subject.h. Unknown keys
/// are rejected (typos would otherwise silently keep a default).

#include <nlohmann/json.hpp>

#include "api/status.h"
#include "server/bench/virtual_subject.h"

namespace fesbench::server {

/// Every field, including defaults. Never fails.
nlohmann::json VirtualSubjectToJson(const VirtualSubject& subject);
nlohmann::json FidelityToJson(const Fidelity& fidelity);

/// Parses and validates. kInvalidArgument with the dotted field path on:
/// a missing or wrongly typed field; an unknown key; a bad truth parameter
/// set (api::ParameterSetFromJson's message, path prefixed "truth.");
/// threshold_ma < 0; max_tolerated_ma ≤ threshold_ma or > 100; a non-finite
/// number; a negative fidelity magnitude; twitch_variation > 1;
/// hysteresis_angle_deg, friction_velocity_deg_s, fatigue_recovery_s or
/// potentiation_decay_s ≤ 0; anthropometric lengths or mass ≤ 0;
/// accel_distance_m > 1; thigh_elevation_deg outside [−45, 45].
api::Result<VirtualSubject> VirtualSubjectFromJson(const nlohmann::json& json);

/// Validates a subject built in code with the same rules (the truth with
/// model::JointModel and model::ValidateContraction).
api::Status ValidateVirtualSubject(const VirtualSubject& subject);

}  // namespace fesbench::server
