#include "clients/model_cli/cli_io.h"

#include <cmath>
#include <nlohmann/json.hpp>
#include <ostream>
#include <sstream>

#include "api/parameter_set_json.h"

namespace fesbench::cli {
namespace {

bool EndsWith(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

std::string ShortNumber(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

TableFormat ResolveTableFormat(std::string_view name, std::string_view path) {
  if (name == "csv") return TableFormat::kCsv;
  if (name == "sto") return TableFormat::kSto;
  if (name == "json") return TableFormat::kJson;
  if (!name.empty()) {
    throw CliError::Usage("unknown format '" + std::string(name) + "' (want csv, sto or json)");
  }
  if (EndsWith(path, ".sto")) return TableFormat::kSto;
  if (EndsWith(path, ".json")) return TableFormat::kJson;
  return TableFormat::kCsv;
}

model::ParameterSet ReadParameterSetFile(const std::string& path) {
  api::Result<std::string> text = api::ReadTextFile(path);
  if (!text.ok()) throw CliError::BadInput(text.status().message());
  nlohmann::json json;
  try {
    json = nlohmann::json::parse(*text);
  } catch (const nlohmann::json::parse_error& e) {
    throw CliError::BadInput(path + ": invalid JSON: " + e.what());
  }
  api::Result<model::ParameterSet> params = api::ParameterSetFromJson(json);
  if (!params.ok()) {
    const api::Status& s = params.status();
    throw CliError::BadInput(path + ": " + (s.field().empty() ? "" : s.field() + ": ") +
                             s.message());
  }
  return *std::move(params);
}

api::Trial ReadUniformCsv(const std::string& path, std::string_view what,
                          const std::vector<std::string_view>& required_channels) {
  const std::string prefix = std::string(what) + " " + path + ": ";
  api::Result<std::string> text = api::ReadTextFile(path);
  if (!text.ok()) throw CliError::BadInput(std::string(what) + " " + text.status().message());
  api::Result<api::Trial> table = api::TrialFromCsv(*text);
  if (!table.ok()) throw CliError::BadInput(prefix + table.status().message());
  for (std::string_view name : required_channels) {
    if (table->FindChannel(name) == nullptr) {
      throw CliError::BadInput(prefix + "no " + std::string(name) + " column");
    }
  }
  const std::vector<double>& t = *table->Values(api::kTimeChannel);
  // The first interval sets the period; a later sample more than 1 % of a
  // period off the grid is reported at its own line.
  const double period_s = t.size() >= 2 ? t[1] - t[0] : 1.0 / table->sample_rate_hz;
  for (std::size_t i = 2; i < t.size(); ++i) {
    const double expected = t.front() + static_cast<double>(i) * period_s;
    if (std::abs(t[i] - expected) > 0.01 * period_s) {
      throw CliError::BadInput(prefix + "line " + std::to_string(i + 2) + ": t_s " +
                               ShortNumber(t[i]) + " breaks uniform sampling (expected " +
                               ShortNumber(expected) + " at " + ShortNumber(1.0 / period_s) +
                               " Hz)");
    }
  }
  return *std::move(table);
}

model::SampledSignal ChannelAsSignal(const api::Trial& table, std::string_view name) {
  model::SampledSignal signal;
  signal.rate_hz = table.sample_rate_hz;
  signal.t0_s = table.Values(api::kTimeChannel)->front();
  signal.values = *table.Values(name);
  return signal;
}

void WriteTable(const api::Trial& trial, const std::string& path, TableFormat format,
                CliContext& context) {
  std::string text;
  switch (format) {
    case TableFormat::kCsv:
      text = api::TrialToCsv(trial);
      break;
    case TableFormat::kSto:
      text = api::TrialToSto(trial);
      break;
    case TableFormat::kJson:
      text = api::TrialToJson(trial).dump() + "\n";
      break;
  }
  if (path == "-") {
    context.out << text;
    context.out.flush();
    if (!context.out) throw CliError::BadInput("cannot write to standard output");
    return;
  }
  if (api::Status s = api::WriteTextFile(path, text); !s.ok()) {
    throw CliError::BadInput(s.message());
  }
}

}  // namespace fesbench::cli
