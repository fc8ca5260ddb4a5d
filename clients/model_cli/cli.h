#pragma once

/// @file
/// The offline model command line `fesbench-model` as a library: main.cc
/// only forwards to RunModelCli, so the commands can be tested in-process.
///
/// Each command lives in its own source file and adds itself to the CLI11
/// application through a registration function listed in commands.h;
/// adding a command (e.g. `identify`) means one new file, one line in
/// commands.h/cli.cc and one in CMakeLists.txt.
///
/// Exit codes: 0 success; 1 bad input data (a file that cannot be read or
/// written, malformed CSV/JSON, a simulation that fails); 2 usage error
/// (unknown command or option, missing or malformed argument, unknown
/// generator or generator parameter). Every failure prints one line,
/// `fesbench-model: error: <what>`, on the error stream.

#include <CLI/CLI.hpp>
#include <iosfwd>
#include <stdexcept>
#include <string>

namespace fesbench::cli {

inline constexpr int kExitOk = 0;
inline constexpr int kExitBadInput = 1;
inline constexpr int kExitUsage = 2;

/// A failure a command reports to the user: one line of text and an exit
/// code (kExitBadInput or kExitUsage). Thrown by command callbacks and
/// caught by RunModelCli.
class CliError : public std::runtime_error {
 public:
  CliError(int exit_code, const std::string& message)
      : std::runtime_error(message), exit_code_(exit_code) {}
  static CliError Usage(const std::string& message) { return {kExitUsage, message}; }
  static CliError BadInput(const std::string& message) { return {kExitBadInput, message}; }
  int exit_code() const { return exit_code_; }

 private:
  int exit_code_;
};

/// Streams a command writes to ("-" as an output path means `out`).
struct CliContext {
  std::ostream& out;
  std::ostream& err;
};

/// Adds one subcommand to `app`. The subcommand's callback runs the command
/// and throws CliError on failure. `context` outlives the parse.
using CommandRegistrar = void (*)(CLI::App& app, CliContext& context);

/// Runs `fesbench-model` with the given arguments (argv[0] is the program
/// name); returns the exit code. Never throws.
int RunModelCli(int argc, const char* const* argv, std::ostream& out, std::ostream& err);

}  // namespace fesbench::cli
