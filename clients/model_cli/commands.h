#pragma once

/// @file
/// Registration functions of the `fesbench-model` subcommands, one per
/// source file (see cli.h). RunModelCli calls them in the order listed in
/// kCommands (cli.cc).

#include "clients/model_cli/cli.h"

namespace fesbench::cli {

/// `simulate`: a parameter set driven by a stimulus CSV (simulate_command.cc).
void RegisterSimulateCommand(CLI::App& app, CliContext& context);

/// `stimulus`: writes or lists the stimulus/trajectory generators
/// (stimulus_command.cc).
void RegisterStimulusCommand(CLI::App& app, CliContext& context);

/// `identify`: runs an identification method on trial CSVs
/// (identify_command.cc).
void RegisterIdentifyCommand(CLI::App& app, CliContext& context);

/// `example`: writes the example parameter set JSON (example_command.cc).
void RegisterExampleCommand(CLI::App& app, CliContext& context);

}  // namespace fesbench::cli
