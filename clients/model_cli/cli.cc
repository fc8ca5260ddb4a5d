#include "clients/model_cli/cli.h"

#include <exception>
#include <ostream>
#include <string>

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

// One line: CLI11 and library messages may carry newlines.
std::string OneLine(std::string message) {
  for (char& c : message) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  while (!message.empty() && message.back() == ' ') message.pop_back();
  return message;
}

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
    for (CommandRegistrar registrar : kCommands) registrar(app, context);
    try {
      app.parse(argc, argv);
    } catch (const CLI::CallForHelp&) {
      out << app.help();
      return kExitOk;
    } catch (const CLI::CallForAllHelp&) {
      out << app.help("", CLI::AppFormatMode::All);
      return kExitOk;
    } catch (const CLI::ParseError& e) {
      // A subcommand's --help arrives as CallForHelp from the subcommand;
      // it is handled above (app.help() then shows the selected one).
      if (app.get_subcommands().empty() && argc > 1 && argv[1][0] != '-') {
        std::string names;
        for (const CLI::App* sub : app.get_subcommands({})) {
          names += (names.empty() ? "" : ", ") + sub->get_name();
        }
        return Fail(err, kExitUsage,
                    std::string("unknown command '") + argv[1] + "' (commands: " + names + ")");
      }
      return Fail(err, kExitUsage, e.what());
    }
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
