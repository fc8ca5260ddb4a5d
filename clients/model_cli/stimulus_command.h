#pragma once

/// @file
/// `fesbench-model stimulus`: runs a named generator of the model's
/// registries and writes its output as a table, or lists the generators.

#include <iosfwd>
#include <string>
#include <string_view>
#include <vector>

#include "api/trial.h"
#include "model/stimulus_generators.h"

namespace fesbench::cli {

/// Parses `--param` values "name=value" (value a finite number).
/// @throws CliError (usage) naming the malformed entry.
model::GeneratorParams ParseGeneratorParams(const std::vector<std::string>& entries);

/// Sample rate of the trajectory tables `stimulus` writes, Hz (docs/ARCHITECTURE.md, units).
inline constexpr double kTrajectoryRateHz = 200.0;

/// The output of generator `name` with `params`: for a stimulus generator the
/// channels t_s, stim_ma at model::kStimulusRateHz; for a trajectory
/// generator (model/trajectory.h) t_s, angle_deg, velocity_deg_s,
/// accel_deg_s2 at kTrajectoryRateHz from 0 to its duration inclusive.
/// @throws CliError (usage) for an unknown generator or a bad parameter.
api::Trial RunGenerator(std::string_view name, const model::GeneratorParams& params);

/// Writes every generator with its parameters, units, defaults and ranges.
void ListGenerators(std::ostream& out);

}  // namespace fesbench::cli
