#include "clients/model_cli/cli.h"

#include <exception>
#include <ostream>
#include <string>

#include "clients/command_line.h"
#include "clients/model_cli/commands.h"

namespace fesbench::cli {
namespace {

// Every subcommand, in the order `--help` lists them. A new command adds
// its registration function here (and its source file to CMakeLists.txt).
constexpr CommandRegistrar kCommands[] = {
    RegisterSimulateCommand,
    RegisterStimulusCommand,
    RegisterIdentifyCommand,
    RegisterExampleCommand,
};

int Fail(std::ostream& err, int code, const std::string& message) {
  err << "fesbench-model: error: " << OneLine(message) << std::endl;
  return code;
}

}  // namespace

int RunModelCli(int argc, const char* const* argv, std::ostream& out, std::ostream& err) {
  try {
    CliContext context{out, err};
    CLI::App app(
        "fesbench-model: offline muscle-joint model tools (simulate, generate stimuli, identify).\n"
        "Exit codes: 0 ok, 1 bad input data, 2 usage error.",
        "fesbench-model");
    app.require_subcommand(1);
    app.fallthrough(false);
    app.set_version_flag("--version", std::string("fesbench-model ") + FESBENCH_VERSION);
    for (CommandRegistrar registrar : kCommands) registrar(app, context);
    const ParseOutcome parsed = ParseCommandLine(app, argc, argv, out);
    if (parsed.help_printed) return kExitOk;
    if (!parsed.usage_error.empty()) return Fail(err, kExitUsage, parsed.usage_error);
    return kExitOk;
  } catch (const CliError& e) {
    return Fail(err, e.exit_code(), e.what());
  } catch (const std::exception& e) {
    return Fail(err, kExitBadInput, e.what());
  } catch (...) {
    return Fail(err, kExitBadInput, "unexpected failure");
  }
}

}  // namespace fesbench::cli
