#pragma once

/// @file
/// Output helpers shared by the commands: aligned tables, JSON values as
/// table cells, ids from arguments, writing to a file or standard output.

#include <cstdint>
#include <iosfwd>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "clients/cli/cli.h"

namespace fesbench::cli {

/// Left-aligned columns separated by two spaces, a header row first.
void PrintTable(std::ostream& out, const std::vector<std::string>& headers,
                const std::vector<std::vector<std::string>>& rows);

/// A JSON value as a table cell: strings bare, null as "-", numbers in the
/// shortest form with at most 6 significant digits, arrays comma-joined.
std::string Cell(const nlohmann::json& value);

/// `key: value` lines of an object's scalar members (and arrays of
/// scalars); nested objects are printed as indented blocks.
void PrintObject(std::ostream& out, const nlohmann::json& object, int indent = 0);

/// A positive integer id; throws CliError (usage) naming `what`.
std::int64_t ParseId(const std::string& text, const std::string& what);

/// Writes `text` to `path`, or to `context.out` when path is "-"; throws
/// CliError (kExitServer class: 1) if the file cannot be written.
void WriteOutput(CliContext& context, const std::string& path, const std::string& text);

/// `key=value` with a finite number value; throws CliError (usage).
std::pair<std::string, double> ParseKeyValue(const std::string& text);

/// A protocol parameter: `key=value` with a number, or with a choice's name
/// (lower-case letters and `_`, e.g. `controller=adaptive`; the server
/// checks it against the protocol's choices); throws CliError (usage).
std::pair<std::string, nlohmann::json> ParseRunParameter(const std::string& text);

}  // namespace fesbench::cli
