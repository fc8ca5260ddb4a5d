#pragma once

/// @file
/// What both command lines (`fesbench`, `fesbench-model`) do around CLI11:
/// parse, print help, and turn every parse failure into one usage line.

#include <CLI/CLI.hpp>

#include <ostream>
#include <string>

namespace fesbench::cli {

/// `message` with line breaks replaced by spaces and trailing spaces
/// dropped: errors are one line (CLI11, server and library messages may
/// carry newlines).
inline std::string OneLine(std::string message) {
  for (char& c : message) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  while (!message.empty() && message.back() == ' ') message.pop_back();
  return message;
}

/// The outcome of ParseCommandLine.
struct ParseOutcome {
  bool help_printed = false;  ///< --help or --version was asked for and written to `out`.
  std::string usage_error;    ///< non-empty: a usage error, one line.
};

/// Parses argv into `app`; prints help to `out` when asked for. An unknown
/// command is reported with the list of commands.
inline ParseOutcome ParseCommandLine(CLI::App& app, int argc, const char* const* argv,
                                     std::ostream& out) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp&) {
    out << app.help();
    return {true, {}};
  } catch (const CLI::CallForAllHelp&) {
    out << app.help("", CLI::AppFormatMode::All);
    return {true, {}};
  } catch (const CLI::CallForVersion& e) {
    out << e.what() << "\n";
    return {true, {}};
  } catch (const CLI::ParseError& e) {
    if (app.get_subcommands().empty() && argc > 1 && argv[1][0] != '-') {
      std::string names;
      for (const CLI::App* sub : app.get_subcommands({})) {
        names += (names.empty() ? "" : ", ") + sub->get_name();
      }
      return {false, std::string("unknown command '") + argv[1] + "' (commands: " + names + ")"};
    }
    return {false, OneLine(e.what())};
  }
  return {};
}

}  // namespace fesbench::cli
