// Data in and out for analysts (docs/API.md, "Session archives"): `trials import`,
// `sessions export`, `params curves` (long tidy CSV) and the wide parameter
// history of `params list --format csv`. Numbers in CSV are the shortest form that reads back
// exactly (std::to_chars).

#include <charconv>
#include <cmath>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "api/import_result.h"
#include "api/json_fields.h"
#include "api/model_call.h"
#include "api/parameter_set_json.h"
#include "api/parameter_set_record.h"
#include "api/time_utc.h"
#include "api/trial.h"
#include "api/trial_import.h"
#include "clients/cli/commands.h"
#include "clients/cli/output.h"
#include "model/joint_model.h"

namespace fesbench::cli {
namespace {

using nlohmann::json;

std::string Shortest(double v) {
  char buffer[32];
  const auto [ptr, ec] = std::to_chars(buffer, buffer + sizeof buffer, v);
  return std::string(buffer, ec == std::errc() ? ptr : buffer);
}

// A CSV cell of a JSON scalar: numbers shortest, strings quoted when needed.
std::string CsvCell(const json& v) {
  if (v.is_null()) return "";
  if (v.is_number_integer()) return std::to_string(v.get<std::int64_t>());
  if (v.is_number()) return Shortest(v.get<double>());
  std::string text = v.is_string()    ? v.get<std::string>()
                     : v.is_boolean() ? (v.get<bool>() ? "true" : "false")
                                      : v.dump();
  if (text.find_first_of(",\"\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

// The scalar leaves of a JSON object as dotted paths (arrays left out: the
// curves go to `params curves`).
void ScalarLeaves(const json& value, const std::string& path,
                  std::vector<std::pair<std::string, json>>& out) {
  if (value.is_object()) {
    for (const auto& [key, item] : value.items()) {
      ScalarLeaves(item, path.empty() ? key : path + "." + key, out);
    }
  } else if (!value.is_array()) {
    out.emplace_back(path, value);
  }
}

std::string ReadFileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw CliError::Usage("cannot open " + path);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

bool IsArchivePath(const std::string& path) {
  return path.ends_with(".zip") || path.ends_with(".tar.gz") || path.ends_with(".tgz");
}

// COLUMN=CHANNEL or COLUMN=CHANNEL:UNIT.
api::ImportColumn ParseMapping(const std::string& text) {
  const std::size_t eq = text.rfind('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == text.size()) {
    throw CliError::Usage("--map wants COLUMN=CHANNEL[:UNIT], got '" + text + "'");
  }
  const std::string target = text.substr(eq + 1);
  const std::size_t colon = target.find(':');
  api::ImportColumn m;
  m.column = text.substr(0, eq);
  m.channel = target.substr(0, colon);
  if (colon != std::string::npos) m.unit = target.substr(colon + 1);
  return m;
}

struct ImportForm {
  std::string session;
  std::string file;
  std::string kind;
  std::string format;
  std::vector<std::string> maps;
  std::vector<std::string> ignore;
  std::string time_column;
  std::string time_unit;
  double rate_hz = 0.0;
  std::string source;
  std::int64_t start_ms = 0;
};

void PrintImportResult(CliContext& context, const json& answer) {
  if (context.options.json) {
    context.out << answer.dump(2) << "\n";
    return;
  }
  const api::ImportResult result = FromServer(api::ImportResultFromJson(answer), "import result");
  std::vector<std::vector<std::string>> rows;
  for (const api::ImportedItem& t : result.trials) {
    rows.push_back({"trial", Cell(t.id), Cell(api::OrNull(t.original_id)), t.name});
  }
  for (const api::ImportedItem& s : result.parameter_sets) {
    rows.push_back({"parameter set", Cell(s.id), Cell(api::OrNull(s.original_id)), s.name});
  }
  PrintTable(context.out, {"imported", "id", "original_id", "name"}, rows);
  for (const std::string& note : result.notes) context.out << "note: " << note << "\n";
}

void RegisterTrialsImport(CLI::App& trials, CliContext& context) {
  auto form = std::make_shared<ImportForm>();
  CLI::App* import = trials.add_subcommand(
      "import",
      "Import a recording made elsewhere (CSV, TSV or OpenSim .sto with --kind and --map), or "
      "a session archive from `sessions export` (.zip, .tar.gz), into a session.");
  import->add_option("--session", form->session, "session id")->required();
  import->add_option("file", form->file, "the recording or archive")->required();
  import->add_option("--kind", form->kind,
                     "trial kind, e.g. free_swing_passive (GET /trial-kinds lists them)");
  import->add_option("--format", form->format, "csv, tsv or sto (default: from the file name)")
      ->check(CLI::IsMember({"csv", "tsv", "sto"}));
  import->add_option("--map", form->maps,
                     "COLUMN=CHANNEL[:UNIT], e.g. knee_angle_r=angle_deg:rad (repeat)");
  import->add_option("--ignore", form->ignore, "a column to leave out (repeat)");
  import->add_option("--time-column", form->time_column,
                     "the time column (default t_s, or "
                     "time for .sto)");
  import->add_option("--time-unit", form->time_unit, "s, ms or us")
      ->check(CLI::IsMember({"s", "ms", "us"}));
  import->add_option("--rate-hz", form->rate_hz, "the nominal sample rate, checked")
      ->check(CLI::PositiveNumber);
  import->add_option("--source", form->source, "where it was recorded (kept as provenance)");
  import->add_option("--start-time-ms", form->start_ms, "recording start, ms since 1970 UTC");
  import->callback([form, &context] {
    context.action = [form, &context] {
      const std::int64_t session_id = ParseId(form->session, "session");
  const std::string path = "/sessions/" + std::to_string(session_id) + "/trials";
  auto client = Connect(context);
  const std::string bytes = ReadFileBytes(form->file);
  if (IsArchivePath(form->file)) {
    if (!form->kind.empty() || !form->maps.empty()) {
      throw CliError::Usage("an archive carries its own kinds and channels: drop --kind/--map");
    }
    const std::string name = form->file.substr(form->file.find_last_of('/') + 1);
    PrintImportResult(
        context,
        client->PostBytes(path + "?name=" + UrlEncode(name), bytes,
                          form->file.ends_with(".zip") ? "application/zip" : "application/gzip"));
    return;
  }
  if (form->kind.empty()) throw CliError::Usage("--kind is required for a recording");
  std::string format = form->format;
  if (format.empty()) {
    format = form->file.ends_with(".sto") || form->file.ends_with(".mot") ? "sto"
             : form->file.ends_with(".tsv")                               ? "tsv"
                                                                          : "csv";
  }
  api::ImportSpec spec;
  spec.kind = form->kind;
  spec.format = format;
  for (const std::string& m : form->maps) spec.columns.push_back(ParseMapping(m));
  spec.ignore = form->ignore;
  spec.time_column = form->time_column;
  if (!form->time_unit.empty()) spec.time_unit = form->time_unit;
  if (form->rate_hz > 0.0) spec.sample_rate_hz = form->rate_hz;
  if (form->start_ms != 0) spec.start_time_unix_ms = form->start_ms;
  spec.source =
      form->source.empty() ? form->file.substr(form->file.find_last_of('/') + 1) : form->source;
  PrintImportResult(context,
                    client->Post(path, {{"spec", api::ImportSpecToJson(spec)}, {"data", bytes}}));
};
}  // namespace
);
}  // namespace fesbench::cli

void RegisterSessionsExport(CLI::App& sessions, CliContext& context) {
  auto id = std::make_shared<std::string>();
  auto format = std::make_shared<std::string>("zip");
  auto out_path = std::make_shared<std::string>();
  CLI::App* exp = sessions.add_subcommand(
      "export",
      "The whole session as one archive laid out after BIDS (trials, pulses, EMG, parameter "
      "sets, run log, README).");
  exp->add_option("id", *id, "session id")->required();
  exp->add_option("--format", *format, "zip (default) or tar.gz")
      ->check(CLI::IsMember({"zip", "tar.gz"}));
  exp->add_option("--out", *out_path, "output file (default fesbench-session-ID.zip|.tar.gz)");
  exp->callback([id, format, out_path, &context] {
    context.action = [id, format, out_path, &context] {
      const std::int64_t session_id = ParseId(*id, "session");
      auto client = Connect(context);
      const std::string bytes = client->GetBytes("/sessions/" + std::to_string(session_id) +
                                                 "/export?format=" + UrlEncode(*format));
      const std::string path =
          out_path->empty() ? "fesbench-session-" + std::to_string(session_id) + "." + *format
                            : *out_path;
      if (path == "-") throw CliError::Usage("an archive is not written to standard output");
      WriteOutput(context, path, bytes);
      if (context.options.json) {
        context.out << json{{"session_id", session_id},
                            {"format", *format},
                            {"out", path},
                            {"bytes", bytes.size()}}
                           .dump(2)
                    << "\n";
      } else {
        context.out << "wrote " << path << " (" << bytes.size() << " bytes)\n";
      }
    };
  });
}

void RegisterParamsCurves(CLI::App& params, CliContext& context) {
  auto id = std::make_shared<std::string>();
  auto out_path = std::make_shared<std::string>("-");
  CLI::App* curves = params.add_subcommand(
      "curves",
      "A parameter set's curves as long tidy CSV (curve,x,x_unit,y,y_unit): the recruitment "
      "curve at its breakpoints, the passive and active curves on a 1° / 5 deg/s grid.");
  curves->add_option("id", *id, "parameter set id")->required();
  curves->add_option("--out", *out_path, "output file ('-' for standard output, the default)");
  curves->callback([id, out_path, &context] {
    context.action = [id, out_path, &context] {
      const std::int64_t set_id = ParseId(*id, "parameter set");
      auto client = Connect(context);
      const api::StoredParameterSet stored = FromServer(
          api::StoredParameterSetFromJson(client->Get("/parameter-sets/" + std::to_string(set_id))),
          "parameter set");
      const std::optional<model::ParameterSet> params = stored.parameters;
      if (!params) throw CliError::Server("server: parameter set " + *id + " has no parameters");
      api::Result<model::JointModel> usable =
          api::CallModel([&] { return model::JointModel::FromParameters(*params); });
      if (!usable.ok()) {
        throw CliError::Server("server sent an unusable parameter set: " +
                               usable.status().message());
      }
      const model::JointModel& joint = *usable;
      struct Point {
        std::string curve, x_unit, y_unit;
        double x, y;
      };
      std::vector<Point> points;
      for (std::size_t i = 0; i < params->irc.x().size(); ++i) {
        points.push_back({"irc", "mA", "1", params->irc.x()[i], params->irc.y()[i]});
      }
      for (int a = 0; a <= 130; ++a) {
        points.push_back({"tau_pta", "deg", "N.m", double(a), joint.PassiveAngleTorque(a)});
      }
      for (int v = -400; v <= 400; v += 5) {
        points.push_back({"tau_ptv", "deg/s", "N.m", double(v), joint.PassiveVelocityTorque(v)});
      }
      for (int a = 0; a <= 130; ++a) {
        points.push_back({"f_ata", "deg", "1", double(a), joint.AngleGain(a)});
      }
      for (int v = -400; v <= 400; v += 5) {
        points.push_back({"f_atv", "deg/s", "1", double(v), joint.VelocityGain(v)});
      }
      if (context.options.json && *out_path == "-") {
        json out = json::array();
        for (const Point& p : points) {
          out.push_back({{"curve", p.curve},
                         {"x", p.x},
                         {"x_unit", p.x_unit},
                         {"y", p.y},
                         {"y_unit", p.y_unit}});
        }
        context.out << out.dump(2) << "\n";
        return;
      }
      std::string csv = "curve,x,x_unit,y,y_unit\n";
      for (const Point& p : points) {
        csv += p.curve + "," + Shortest(p.x) + "," + p.x_unit + "," + Shortest(p.y) + "," +
               p.y_unit + "\n";
      }
      WriteOutput(context, *out_path, csv);
    };
  });
}

void RegisterReport(CLI::App& app, CliContext& context) {
  auto id = std::make_shared<std::string>();
  auto out_path = std::make_shared<std::string>();
  CLI::App* report = app.add_subcommand(
      "report",
      "A session's report: one self-contained HTML page to file or print to PDF (subject code, "
      "session values, runs, e-stops and clamps, trials, parameter sets with their curves, "
      "predictions on fresh trials, warnings).");
  report->add_option("session", *id, "session id")->required();
  report->add_option("--out", *out_path,
                     "output file (default fesbench-session-ID-report.html; '-' for standard "
                     "output)");
  report->callback([id, out_path, &context] {
    context.action = [id, out_path, &context] {
      const std::int64_t session_id = ParseId(*id, "session");
      auto client = Connect(context);
      const std::string html =
          client->GetBytes("/sessions/" + std::to_string(session_id) + "/report");
      const std::string path =
          out_path->empty() ? "fesbench-session-" + std::to_string(session_id) + "-report.html"
                            : *out_path;
      WriteOutput(context, path, html);
      if (path == "-") return;
      if (context.options.json) {
        context.out << json{{"session_id", session_id}, {"out", path}, {"bytes", html.size()}}.dump(
                           2)
                    << "\n";
      } else {
        context.out << "wrote " << path << " (" << html.size()
                    << " bytes; open it in a browser, print to PDF to file it)\n";
      }
    };
  });
}

}  // namespace

std::string ParameterHistoryCsv(ApiClient& client, std::int64_t subject_id, const json& items,
                                const std::map<std::int64_t, std::string>& sides) {
  std::vector<std::string> columns = {"parameter_set_id", "subject_id",     "leg",
                                      "version",          "created_at_utc", "supersedes_id"};
  std::set<std::string> seen(columns.begin(), columns.end());
  std::vector<std::map<std::string, json>> rows;
  for (const api::ParameterSetSummary& summary :
       ItemsFromServer(items, &api::ParameterSetSummaryFromJson, "parameter set")) {
    const std::int64_t set_id = summary.id;
    const api::StoredParameterSet stored = FromServer(
        api::StoredParameterSetFromJson(client.Get("/parameter-sets/" + std::to_string(set_id))),
        "parameter set");
    const auto side = sides.find(summary.leg_id);
    std::map<std::string, json> row = {
        {"parameter_set_id", set_id},
        {"subject_id", subject_id},
        {"leg", side == sides.end() ? json(nullptr) : json(side->second)},
        {"version", summary.version},
        {"created_at_utc", api::FormatUtc(summary.created_at)},
        {"supersedes_id", api::OrNull(summary.supersedes_id)}};
    std::vector<std::pair<std::string, json>> leaves;
    ScalarLeaves(stored.parameters ? api::ParameterSetToJson(*stored.parameters) : json::object(),
                 "", leaves);
    for (auto& [key, value] : leaves) {
      if (seen.insert(key).second) columns.push_back(key);
      row[key] = std::move(value);
    }
    rows.push_back(std::move(row));
  }
  std::string csv;
  for (std::size_t c = 0; c < columns.size(); ++c) csv += (c ? "," : "") + columns[c];
  csv += "\n";
  for (const auto& row : rows) {
    for (std::size_t c = 0; c < columns.size(); ++c) {
      const auto it = row.find(columns[c]);
      csv += (c ? "," : "") + (it == row.end() ? std::string() : CsvCell(it->second));
    }
    csv += "\n";
  }
  return csv;
}

void RegisterExchangeCommands(CLI::App& app, CliContext& context) {
  RegisterTrialsImport(*app.get_subcommand("trials"), context);
  RegisterSessionsExport(*app.get_subcommand("sessions"), context);
  RegisterParamsCurves(*app.get_subcommand("params"), context);
  RegisterReport(app, context);
}

}  // namespace fesbench::cli
