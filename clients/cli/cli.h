#pragma once

/// @file
/// The analyst command line `fesbench` as a library: main.cc only forwards
/// to RunFesbenchCli, so the commands can be exercised from tests.
///
/// Each command group lives in its own source file and adds itself to the
/// CLI11 application through a registration function listed in commands.h.
/// A command's callback does not talk to the server itself: it stores the
/// work in CliContext::action, which RunFesbenchCli runs once the whole
/// command line has parsed (so global options such as --server are known).
///
/// Exit codes: 0 success; 1 an error reported by the server (its message
/// printed) or a local file that cannot be written; 2 usage error (unknown
/// command or option, malformed argument, no server configured); 3 the
/// server cannot be reached. Every failure prints one line,
/// `fesbench: error: <what>`, on the error stream.

#include <CLI/CLI.hpp>
#include <functional>
#include <iosfwd>
#include <stdexcept>
#include <string>

namespace fesbench::cli {

inline constexpr int kExitOk = 0;
inline constexpr int kExitServer = 1;
inline constexpr int kExitUsage = 2;
inline constexpr int kExitUnreachable = 3;
/// Interrupted (Ctrl-C) after the server confirmed the run was cancelled (128 + SIGINT).
inline constexpr int kExitInterrupted = 130;

/// A failure a command reports to the user: one line of text and an exit
/// code. Thrown by actions and caught by RunFesbenchCli.
class CliError : public std::runtime_error {
 public:
  CliError(int exit_code, const std::string& message)
      : std::runtime_error(message), exit_code_(exit_code) {}
  static CliError Usage(const std::string& message) { return {kExitUsage, message}; }
  static CliError Server(const std::string& message) { return {kExitServer, message}; }
  static CliError Unreachable(const std::string& message) { return {kExitUnreachable, message}; }
  int exit_code() const { return exit_code_; }

 private:
  int exit_code_;
};

/// Global options, filled by the parse.
struct GlobalOptions {
  std::string server;      ///< --server URL (overrides the config file).
  std::string token_file;  ///< --token-file PATH ("-": standard input); overrides the rest.
  std::string token;       ///< the token read from token_file once the command line parsed.
  bool json = false;       ///< --json: machine-readable JSON output of every command.
};

/// What a command writes to and where it runs.
struct CliContext {
  std::ostream& out;
  std::ostream& err;
  bool out_is_terminal = false;  ///< progress bar (true) or plain lines (false).
  GlobalOptions options;
  std::function<void()> action;  ///< set by the chosen subcommand's callback.
};

/// Adds one command (or command group) to `app`. `context` outlives the parse.
using CommandRegistrar = void (*)(CLI::App& app, CliContext& context);

/// Runs `fesbench` with the given arguments (argv[0] is the program name);
/// returns the exit code. Never throws.
int RunFesbenchCli(int argc, const char* const* argv, std::ostream& out, std::ostream& err,
                   bool out_is_terminal = false);

}  // namespace fesbench::cli
