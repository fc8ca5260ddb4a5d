#pragma once

/// @file
/// File helpers shared by the `fesbench-model` commands. Every failure is a
/// CliError (exit code kExitBadInput) whose message names the file and, for
/// CSV, the line and column.

#include <string>
#include <string_view>
#include <vector>

#include "api/trial.h"
#include "clients/model_cli/cli.h"
#include "model/parameter_set.h"
#include "model/signal.h"

namespace fesbench::cli {

/// Output formats of a table of channels.
enum class TableFormat { kCsv, kSto, kJson };

/// Parses "csv", "sto" or "json"; an empty name picks the format from the
/// path's extension (.sto, .json, otherwise CSV).
/// @throws CliError (usage) for an unknown name.
TableFormat ResolveTableFormat(std::string_view name, std::string_view path);

/// Reads and validates a parameter set JSON file (api::ParameterSetFromJson).
model::ParameterSet ReadParameterSetFile(const std::string& path);

/// Reads a CSV table, requires the named channels and uniform sampling
/// (every t_s within 1 % of a period of t_0 + i / rate). `what` names the
/// file's role in messages ("stimulus", "trajectory").
api::Trial ReadUniformCsv(const std::string& path, std::string_view what,
                          const std::vector<std::string_view>& required_channels);

/// Channel `name` of a CSV read by ReadUniformCsv as a sampled signal.
model::SampledSignal ChannelAsSignal(const api::Trial& table, std::string_view name);

/// Writes the trial's main channels to `path` ("-": context.out) in `format`.
void WriteTable(const api::Trial& trial, const std::string& path, TableFormat format,
                CliContext& context);

}  // namespace fesbench::cli
