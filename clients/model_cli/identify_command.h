#pragma once

/// @file
/// `fesbench-model identify METHOD --trial T.csv [--trial ...]
/// [--params-in P.json] [--option k=v ...] --out P.json`: runs one
/// identification method of model/identify_*.h on recorded or simulated
/// trials and writes the resulting parameter set; the report (fit RMS,
/// figures, warnings) goes to standard output as JSON.

#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "model/identify_common.h"
#include "model/parameter_set.h"

namespace fesbench::cli {

/// Every method name, in --help order: contraction, irc_step, irc_impulse,
/// irc_ramp_correlation, irc_ramp_deconvolution_ideal,
/// irc_ramp_deconvolution_measured, passive_sequential (trials: positions
/// then velocities), passive_simultaneous, passive_free_swing (τ_pta from
/// --params-in), active (passive from --params-in), output_error (the
/// rapid routine's output-error refinement of --params-in on free-swing
/// trials; iterations=0 evaluates the set), torque_generator,
/// single_segment, static_gain_pwl_velocity, parametric.
const std::vector<std::string>& IdentifyMethodNames();

/// Runs `method` on `trials` starting from `params_in` (fields the method
/// does not identify are kept) with `options` (k → v). Conditioning options
/// apply to every trial first: offset_samples=N (remove the mean of the
/// first N torque samples), derive_kinematics=gcv (velocity and
/// acceleration from a GCV smoothing spline of the angle),
/// accel_calibration_trial=I (gravity table from the holds of trial I,
/// 0-based, applied to all). A missing activation column is computed from
/// stim_ma, the IRC and the contraction dynamics of params_in.
/// @throws CliError (usage) for an unknown method or option or a malformed
///   value; (bad input) when the method rejects the data.
model::ParameterSet RunIdentify(std::string_view method, std::vector<model::TrialColumns> trials,
                                const model::ParameterSet& params_in,
                                const std::map<std::string, std::string>& options,
                                model::IdentifyReport* report);

}  // namespace fesbench::cli
