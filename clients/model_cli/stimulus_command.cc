#include "clients/model_cli/stimulus_command.h"

#include <charconv>
#include <cmath>
#include <memory>
#include <ostream>

#include "api/model_call.h"
#include "clients/model_cli/cli_io.h"
#include "clients/model_cli/commands.h"
#include "model/trajectory.h"

namespace fesbench::cli {
namespace {

// Shortest form that reads back exactly (a 32-bit seed limit stays whole).
std::string FormatNumber(double v) {
  char buffer[32];
  const auto [ptr, ec] = std::to_chars(buffer, buffer + sizeof buffer, v);
  return std::string(buffer, ec == std::errc() ? ptr : buffer);
}

std::string UnitOf(std::string_view parameter_name) {
  const std::string unit = api::ChannelUnit(parameter_name);
  return unit.empty() ? "-" : unit;
}

void ListRegistry(std::ostream& out, std::string_view kind,
                  const std::vector<model::GeneratorDescription>& generators) {
  for (const model::GeneratorDescription& g : generators) {
    out << g.name << " (" << kind << ")\n    " << g.description << "\n";
    for (const model::GeneratorParameter& p : g.parameters) {
      out << "    " << p.name << "  unit " << UnitOf(p.name) << "  default "
          << FormatNumber(p.default_value) << "  range [" << FormatNumber(p.min_value) << ", "
          << FormatNumber(p.max_value) << "]" << (p.integer ? " integer" : "") << "  "
          << p.description << "\n";
    }
  }
}

struct StimulusArgs {
  std::string name;
  std::vector<std::string> params;
  std::string out_path;
  std::string format;
  bool list = false;
};

void RunStimulusCommand(const StimulusArgs& args, CliContext& context) {
  if (args.list) {
    if (!args.name.empty() || !args.params.empty() || !args.out_path.empty()) {
      throw CliError::Usage("--list takes no generator name, --param or --out");
    }
    ListGenerators(context.out);
    return;
  }
  if (args.name.empty()) {
    throw CliError::Usage("stimulus: give a generator NAME (see 'stimulus --list')");
  }
  if (args.out_path.empty()) throw CliError::Usage("stimulus: --out is required");
  const TableFormat format = ResolveTableFormat(args.format, args.out_path);
  const api::Trial table = RunGenerator(args.name, ParseGeneratorParams(args.params));
  WriteTable(table, args.out_path, format, context);
}

}  // namespace

model::GeneratorParams ParseGeneratorParams(const std::vector<std::string>& entries) {
  model::GeneratorParams params;
  for (const std::string& entry : entries) {
    const std::size_t eq = entry.find('=');
    if (eq == std::string::npos || eq == 0) {
      throw CliError::Usage("--param '" + entry + "': expected name=value");
    }
    const std::string name = entry.substr(0, eq);
    std::string_view text = std::string_view(entry).substr(eq + 1);
    if (!text.empty() && text.front() == '+') text.remove_prefix(1);
    double value = 0.0;
    const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (text.empty() || ec != std::errc() || ptr != text.data() + text.size() ||
        !std::isfinite(value)) {
      throw CliError::Usage("--param '" + entry + "': value is not a finite number");
    }
    if (!params.emplace(name, value).second) {
      throw CliError::Usage("--param " + name + " given more than once");
    }
  }
  return params;
}

api::Trial RunGenerator(std::string_view name, const model::GeneratorParams& params) {
  if (model::FindStimulusGenerator(name) != nullptr) {
    api::Result<model::SampledSignal> made =
        api::CallModel([&] { return model::MakeStimulus(name, params); });
    if (!made.ok()) throw CliError::Usage(made.status().message());
    model::SampledSignal envelope = *std::move(made);
    std::vector<double> t_s(envelope.size());
    for (std::size_t i = 0; i < t_s.size(); ++i) t_s[i] = envelope.TimeAt(i);
    api::Trial table;
    table.name = std::string(name);
    table.sample_rate_hz = envelope.rate_hz;
    table.SetChannel("t_s", std::move(t_s));
    table.SetChannel("stim_ma", std::move(envelope.values));
    return table;
  }
  if (model::FindTrajectoryGenerator(name) != nullptr) {
    api::Result<model::TrajectorySamples> sampled = api::CallModel([&] {
      return model::SampleTrajectory(*model::MakeTrajectory(name, params), kTrajectoryRateHz);
    });
    if (!sampled.ok()) throw CliError::Usage(sampled.status().message());
    model::TrajectorySamples samples = *std::move(sampled);
    std::vector<double> t_s(samples.angle_deg.size());
    for (std::size_t i = 0; i < t_s.size(); ++i) {
      t_s[i] = static_cast<double>(i) / samples.rate_hz;
    }
    api::Trial table;
    table.name = std::string(name);
    table.sample_rate_hz = samples.rate_hz;
    table.SetChannel("t_s", std::move(t_s));
    table.SetChannel("angle_deg", std::move(samples.angle_deg));
    table.SetChannel("velocity_deg_s", std::move(samples.velocity_deg_s));
    table.SetChannel("accel_deg_s2", std::move(samples.accel_deg_s2));
    return table;
  }
  throw CliError::Usage("unknown generator '" + std::string(name) +
                        "' (see 'fesbench-model stimulus --list')");
}

void ListGenerators(std::ostream& out) {
  out << "Stimulus generators (output t_s, stim_ma at " << FormatNumber(model::kStimulusRateHz)
      << " Hz). Set parameters with --param name=value.\n";
  ListRegistry(out, "stimulus", model::StimulusGenerators());
  out << "\nTrajectory generators (output t_s, angle_deg, velocity_deg_s, accel_deg_s2 at "
      << FormatNumber(kTrajectoryRateHz) << " Hz, for simulate --mode trajectory).\n";
  ListRegistry(out, "trajectory", model::TrajectoryGenerators());
}

void RegisterStimulusCommand(CLI::App& app, CliContext& context) {
  auto args = std::make_shared<StimulusArgs>();
  CLI::App* sub = app.add_subcommand(
      "stimulus", "Write the output of a named stimulus or trajectory generator, or list them.");
  sub->add_option("name", args->name, "generator name (see --list)");
  sub->add_option("--param", args->params, "generator parameter name=value (repeatable)")
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  sub->add_option("--out", args->out_path, "output file ('-' for standard output)");
  sub->add_option("--format", args->format,
                  "output format (default from the --out extension: .sto, .json, else csv)")
      ->check(CLI::IsMember({"csv", "sto", "json"}));
  sub->add_flag("--list", args->list, "list the generators with their parameters");
  sub->callback([args, &context] { RunStimulusCommand(*args, context); });
}

}  // namespace fesbench::cli
