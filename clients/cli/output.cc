#include "clients/cli/output.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <ostream>

#include "api/trial.h"

namespace fesbench::cli {

using nlohmann::json;

namespace {

// Columns a UTF-8 cell takes on a terminal: its code points (units such as
// "N·m" and "kg·m²" are multi-byte).
std::size_t DisplayWidth(const std::string& text) {
  return static_cast<std::size_t>(std::count_if(text.begin(), text.end(), [](char c) {
    return (static_cast<unsigned char>(c) & 0xC0) != 0x80;
  }));
}

}  // namespace

void PrintTable(std::ostream& out, const std::vector<std::string>& headers,
                const std::vector<std::vector<std::string>>& rows) {
  std::vector<std::size_t> widths(headers.size(), 0);
  for (std::size_t c = 0; c < headers.size(); ++c) widths[c] = DisplayWidth(headers[c]);
  for (const auto& row : rows) {
    for (std::size_t c = 0; c < row.size() && c < widths.size(); ++c) {
      widths[c] = std::max(widths[c], DisplayWidth(row[c]));
    }
  }
  auto print_row = [&](const std::vector<std::string>& row) {
    std::string line;
    for (std::size_t c = 0; c < widths.size(); ++c) {
      const std::string cell = c < row.size() ? row[c] : std::string();
      line += cell;
      if (c + 1 < widths.size()) line += std::string(widths[c] - DisplayWidth(cell) + 2, ' ');
    }
    while (!line.empty() && line.back() == ' ') line.pop_back();
    out << line << "\n";
  };
  print_row(headers);
  for (const auto& row : rows) print_row(row);
}

std::string Cell(const json& value) {
  if (value.is_null()) return "-";
  if (value.is_string()) return value.get<std::string>();
  if (value.is_boolean()) return value.get<bool>() ? "yes" : "no";
  if (value.is_number_integer()) return std::to_string(value.get<std::int64_t>());
  if (value.is_number()) {
    char buffer[32];
    std::snprintf(buffer, sizeof buffer, "%.6g", value.get<double>());
    return buffer;
  }
  if (value.is_array()) {
    std::string joined;
    for (const auto& item : value) joined += (joined.empty() ? "" : ",") + Cell(item);
    return joined;
  }
  return value.dump();
}

void PrintObject(std::ostream& out, const json& object, int indent) {
  const std::string pad(static_cast<std::size_t>(indent), ' ');
  if (!object.is_object()) {
    out << pad << Cell(object) << "\n";
    return;
  }
  for (const auto& [key, value] : object.items()) {
    const bool nested_array =
        value.is_array() && std::any_of(value.begin(), value.end(), [](const json& v) {
          return v.is_object() || v.is_array();
        });
    if (value.is_object() || nested_array) {
      out << pad << key << ":\n";
      if (value.is_object()) {
        PrintObject(out, value, indent + 2);
      } else {
        for (const auto& item : value) {
          out << pad << "  -\n";
          PrintObject(out, item, indent + 4);
        }
      }
    } else {
      out << pad << key << ": " << Cell(value) << "\n";
    }
  }
}

std::int64_t ParseId(const std::string& text, const std::string& what) {
  std::int64_t id = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), id);
  if (ec != std::errc() || end != text.data() + text.size() || id <= 0) {
    throw CliError::Usage(what + " must be a positive integer id, got '" + text + "'");
  }
  return id;
}

void WriteOutput(CliContext& context, const std::string& path, const std::string& text) {
  if (path == "-") {
    context.out << text;
    return;
  }
  const api::Status written = api::WriteTextFile(path, text);
  if (!written.ok()) throw CliError(kExitServer, written.ToString());
}

std::pair<std::string, double> ParseKeyValue(const std::string& text) {
  const std::size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw CliError::Usage("--param must be key=value, got '" + text + "'");
  }
  const std::string key = text.substr(0, eq);
  const std::string number = text.substr(eq + 1);
  double value = 0.0;
  const auto [end, ec] = std::from_chars(number.data(), number.data() + number.size(), value);
  if (ec != std::errc() || end != number.data() + number.size() || !std::isfinite(value)) {
    throw CliError::Usage("--param " + key + " must be a number, got '" + number + "'");
  }
  return {key, value};
}

std::pair<std::string, nlohmann::json> ParseRunParameter(const std::string& text) {
  const std::size_t eq = text.find('=');
  const std::string value = eq == std::string::npos ? std::string() : text.substr(eq + 1);
  const bool name = !value.empty() && std::all_of(value.begin(), value.end(), [](char c) {
    return std::islower(static_cast<unsigned char>(c)) || c == '_';
  });
  if (eq != std::string::npos && eq > 0 && name) return {text.substr(0, eq), value};
  const auto [key, number] = ParseKeyValue(text);
  return {key, number};
}

}  // namespace fesbench::cli
