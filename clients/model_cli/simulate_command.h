#pragma once

/// @file
/// `fesbench-model simulate`: forward simulation of a parameter set under a
/// stimulation envelope (model/simulate.h), as a function for tests and as
/// the CLI subcommand registered by RegisterSimulateCommand.

#include <optional>
#include <string_view>

#include "api/status.h"
#include "api/trial.h"
#include "model/parameter_set.h"
#include "model/signal.h"
#include "model/simulate.h"

namespace fesbench::cli {

/// The bench mode simulated (docs/MODEL.md, "Simulation").
enum class SimulateMode { kFreeSwing, kIsometric, kTrajectory };

/// "free_swing", "isometric", "trajectory".
std::string_view SimulateModeName(SimulateMode mode);
std::optional<SimulateMode> ParseSimulateMode(std::string_view name);

/// Output columns of a simulation, in order.
inline constexpr std::string_view kSimulationColumns[] = {
    "t_s", "stim_ma", "angle_deg", "velocity_deg_s", "accel_deg_s2", "torque_nm", "activation"};

/// Simulates `params` driven by the pulses the stimulator makes of
/// `envelope_ma` (model::PulsesFromEnvelope at options.pulse_rate_hz: the
/// pulse clock runs continuously from the envelope's t = 0, docs/MODEL.md).
/// `angle_deg` is the held angle (isometric) or θ(0) (free swing; it
/// overrides options.initial_angle_deg). When options.duration_s is unset
/// the run covers the envelope, [0, envelope.EndTime()), or in trajectory
/// mode the trajectory's samples, [0, trajectory_end_s).
/// @returns a trial with the kSimulationColumns channels at
///   options.output_rate_hz (stim_ma: model::StimulusColumn of the pulses)
///   and the pulses themselves (Trial::pulses, in its JSON form).
/// kInvalidArgument for inputs the model refuses (model/simulate.h; a null
/// trajectory in trajectory mode), kFailedPrecondition for an integration
/// that could not finish (api::CallModel).
api::Result<api::Trial> RunSimulation(const model::ParameterSet& params,
                                      const model::SampledSignal& envelope_ma, SimulateMode mode,
                                      double angle_deg, const model::Trajectory* trajectory,
                                      double trajectory_end_s, model::SimulationOptions options);

}  // namespace fesbench::cli
