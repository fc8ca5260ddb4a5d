// `fesbench params list|get` and `fesbench trials get`: parameter-set
// history and export of parameter sets and recorded trials (docs/MODEL.md,
// docs/API.md) with the api/ wire types.

#include <charconv>
#include <map>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "api/analysis_results.h"
#include "api/json_fields.h"
#include "api/parameter_set_json.h"
#include "api/parameter_set_record.h"
#include "api/subject.h"
#include "api/time_utc.h"
#include "api/trial.h"
#include "api/trial_summary.h"
#include "clients/cli/commands.h"
#include "clients/cli/output.h"

namespace fesbench::cli {

namespace {

using nlohmann::json;

// "field,value" rows of every leaf of a JSON value, fields as dotted paths
// with [i] for array elements (e.g. passive.torque_angle.angle_deg[3]).
void Flatten(const json& value, const std::string& path, std::string& csv) {
  if (value.is_object()) {
    for (const auto& [key, item] : value.items()) {
      Flatten(item, path.empty() ? key : path + "." + key, csv);
    }
  } else if (value.is_array()) {
    for (std::size_t i = 0; i < value.size(); ++i) {
      const std::string element = path + '[' + std::to_string(i) + ']';
      Flatten(value.at(i), element, csv);
    }
  } else if (value.is_number_float()) {
    // The shortest text that reads back to the same double.
    char buffer[32];
    const auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, value.get<double>());
    csv += path + "," + std::string(buffer, ec == std::errc() ? end : buffer) + "\n";
  } else {
    std::string cell = Cell(value);
    if (cell.find_first_of(",\"") != std::string::npos) {
      std::string quoted = "\"";
      for (char c : cell) quoted += (c == '"') ? std::string("\"\"") : std::string(1, c);
      cell = quoted + "\"";
    }
    csv += path + "," + cell + "\n";
  }
}

struct ListForm {
  std::string format = "table";
  std::string subject;
  std::string leg;
  std::string method;
  std::string from;
  std::string to;
};

std::string CheckDate(const std::string& date) {
  return date.size() == 10 && date[4] == '-' && date[7] == '-' ? std::string()
                                                               : "must be YYYY-MM-DD";
}

// With --json a command that writes a file reports what it wrote.
void PrintWritten(CliContext& context, const std::string& what, std::int64_t id,
                  const std::string& format, const std::string& path, std::size_t bytes) {
  context.out
      << nlohmann::json{{what, id}, {"format", format}, {"out", path}, {"bytes", bytes}}.dump(2)
      << "\n";
}

// "yes (cora 2026-11-25T…)" for the leg's approved set; "earlier (…)" for a
// set approved before it; "no" for a candidate never approved.
std::string ApprovedCell(const api::ParameterSetSummary& set) {
  if (!set.approval || !set.approval->newest) return "no";
  const api::Approval& newest = *set.approval->newest;
  const std::string who = newest.approved_by + " " + api::FormatUtc(newest.approved_at);
  return (set.approval->approved ? "yes (" : "earlier (") + who + ")";
}

// `params approve ID --note TEXT`: a clinician makes the set its leg's
// approved set, the one that gates stimulation (docs/SAFETY.md).
void RegisterApprove(CLI::App& params, CliContext& context) {
  auto id = std::make_shared<std::string>();
  auto note = std::make_shared<std::string>();
  CLI::App* approve = params.add_subcommand(
      "approve",
      "Approve a parameter set (clinician): it becomes its leg's approved set, the one the model "
      "gate, tracking and the daily check use.");
  approve->add_option("id", *id, "parameter set id")->required();
  approve->add_option("--note", *note, "why (printable text, at most 500 characters)")->required();
  approve->callback([id, note, &context] {
    context.action = [id, note, &context] {
      const std::int64_t set_id = ParseId(*id, "parameter set");
      auto client = Connect(context);
      const json approved =
          client->Post("/parameter-sets/" + std::to_string(set_id) + "/approve", {{"note", *note}});
      if (context.options.json) {
        json shown = approved;
        shown.erase("parameters");
        context.out << shown.dump(2) << "\n";
        return;
      }
      const api::ParameterSetSummary set =
          FromServer(api::ParameterSetSummaryFromJson(approved), "parameter set");
      context.out << "parameter set " << set_id << " approved for leg " << set.leg_id << ": "
                  << ApprovedCell(set) << "\n";
    };
  });
}

// `params check ID`: the model check (docs/MODEL.md): the set predicts the
// leg's validation trials it was not fitted on; the verdict, each trial's
// error in its own unit and the fit's warnings in a clinician's words.
void RegisterCheck(CLI::App& params, CliContext& context) {
  auto id = std::make_shared<std::string>();
  CLI::App* check = params.add_subcommand(
      "check",
      "The model check: is the set fit to drive stimulation? It predicts the leg's "
      "prediction-protocol trials it was not fitted on (clinician, analyst, admin).");
  check->add_option("id", *id, "parameter set id")->required();
  check->callback([id, &context] {
    context.action = [id, &context] {
      const std::int64_t set_id = ParseId(*id, "parameter set");
      auto client = Connect(context);
      const json job =
          client->Post("/parameter-sets/" + std::to_string(set_id) + "/model-check");
      const json result =
          WaitForJob(*client, FromServer(api::JobReportFromJson(job), "job").id);
      if (context.options.json) {
        context.out << result.dump(2) << "\n";
        return;
      }
      const api::ModelCheck check = FromServer(api::ModelCheckFromJson(result), "model check");
      context.out << "parameter set " << set_id << ": " << api::ModelVerdictName(check.verdict)
                  << "\n"
                  << check.summary << "\n";
      std::vector<std::vector<std::string>> rows;
      for (const api::ModelCheckTrial& t : check.trials) {
        rows.push_back({Cell(json(t.trial_id)), t.trial_name, t.quantity,
                        Cell(api::OrNull(t.e_rms)) + " " + t.unit,
                        std::string(api::ModelVerdictName(t.verdict)), t.explanation});
      }
      if (!rows.empty()) {
        PrintTable(context.out, {"trial", "name", "compared", "e_rms", "verdict", "why"}, rows);
      }
      for (const std::string& w : check.warnings) context.out << "fit: " << w << "\n";
    };
  });
}

}  // namespace

void RegisterDataCommands(CLI::App& app, CliContext& context) {
  CLI::App* params = app.add_subcommand("params", "Parameter sets: history and export.");
  params->require_subcommand(1);
  {
    auto form = std::make_shared<ListForm>();
    CLI::App* list = params->add_subcommand("list", "A subject's parameter-set history.");
    list->add_option("--subject", form->subject, "subject id or code")->required();
    list->add_option("--leg", form->leg, "left or right")->check(CLI::IsMember({"left", "right"}));
    list->add_option("--method", form->method, "identification method (IRC, passive or active)");
    list->add_option("--from", form->from, "created on or after this date (YYYY-MM-DD)")
        ->check(CheckDate);
    list->add_option("--since", form->from, "old spelling of --from")->check(CheckDate)->group("");
    list->add_option("--to", form->to, "created on or before this date (YYYY-MM-DD)")
        ->check(CheckDate);
    list->add_option("--format", form->format,
                     "table (default) or csv: one row per set, one column per scalar "
                     "parameter (curves: params curves ID)")
        ->check(CLI::IsMember({"table", "csv"}));
    list->callback([form, &context] {
      context.action = [form, &context] {
        auto client = Connect(context);
        const std::int64_t subject_id = ResolveSubject(*client, form->subject);
        std::string query = "subject_id=" + std::to_string(subject_id);
        if (!form->leg.empty()) query += "&leg=" + form->leg;
        if (!form->method.empty()) query += "&method=" + UrlEncode(form->method);
        if (!form->from.empty()) query += "&from=" + UrlEncode(form->from);
        if (!form->to.empty()) query += "&to=" + UrlEncode(form->to);
        const json items = client->GetAllPages("/parameter-sets", query);
        if (context.options.json) {
          context.out << items.dump(2) << "\n";
          return;
        }
        // Legs as right/left, not internal ids.
        std::map<std::int64_t, std::string> sides;
        const api::Subject subject = FromServer(
            api::SubjectFromJson(client->Get("/subjects/" + std::to_string(subject_id))),
            "subject");
        for (const api::SubjectLeg& leg : subject.legs) sides[leg.id] = api::SideName(leg.side);
        if (form->format == "csv") {
          context.out << ParameterHistoryCsv(*client, subject_id, items, sides);
          return;
        }
        std::vector<std::vector<std::string>> rows;
        for (const api::ParameterSetSummary& s :
             ItemsFromServer(items, &api::ParameterSetSummaryFromJson, "parameter set")) {
          const auto side = sides.find(s.leg_id);
          rows.push_back({Cell(s.id), side == sides.end() ? Cell(s.leg_id) : side->second,
                          Cell(s.version), s.model, s.irc_method, s.passive_method,
                          s.active_method, Cell(api::OrNull(s.supersedes_id)),
                          api::FormatUtc(s.created_at), ApprovedCell(s)});
        }
        PrintTable(context.out,
                   {"id", "leg", "version", "model", "irc_method", "passive_method",
                    "active_method", "supersedes", "created_at_utc", "approved"},
                   rows);
      };
    });
  }
  {
    auto id = std::make_shared<std::string>();
    auto format = std::make_shared<std::string>("json");
    auto out_path = std::make_shared<std::string>("-");
    CLI::App* get = params->add_subcommand(
        "get",
        "One parameter set: the parameter-set JSON of docs/MODEL.md (as fesbench-model reads "
        "it) or CSV; with --json and no --out, the stored set with its provenance.");
    get->add_option("id", *id, "parameter set id")->required();
    CLI::Option* format_option =
        get->add_option("--format", *format, "json or csv (field,value rows)")
            ->check(CLI::IsMember({"json", "csv"}));
    get->add_option("--out", *out_path, "output file ('-' for standard output, the default)");
    get->callback([id, format, format_option, out_path, &context] {
      context.action = [id, format, format_option, out_path, &context] {
        const std::int64_t set_id = ParseId(*id, "parameter set");
        const bool to_stdout = *out_path == "-";
        if (context.options.json && to_stdout && format_option->count() > 0 && *format != "json") {
          throw CliError::Usage("--json writes JSON: drop --format " + *format +
                                " or write it to a file with --out FILE");
        }
        auto client = Connect(context);
        const json stored = client->Get("/parameter-sets/" + std::to_string(set_id));
        if (context.options.json && to_stdout) {
          context.out << stored.dump(2) << "\n";
          return;
        }
        // Checked with the wire type, so what is written reads back.
        const api::StoredParameterSet set =
            FromServer(api::StoredParameterSetFromJson(stored), "parameter set");
        if (!set.parameters) {
          throw CliError::Server("server: parameter set " + *id + " has no parameters");
        }
        const json params_json = api::ParameterSetToJson(*set.parameters);
        std::string text;
        if (*format == "json") {
          text = params_json.dump(2) + "\n";
        } else {
          text = "field,value\n";
          json provenance = stored;
          provenance.erase("parameters");
          Flatten(provenance, "provenance", text);
          Flatten(params_json, "", text);
        }
        WriteOutput(context, *out_path, text);
        if (context.options.json) {
          PrintWritten(context, "parameter_set_id", set_id, *format, *out_path, text.size());
        }
      };
    });
  }

  RegisterApprove(*params, context);
  RegisterCheck(*params, context);

  CLI::App* trials = app.add_subcommand("trials", "Recorded trials: list, export.");
  trials->require_subcommand(1);
  {
    auto session = std::make_shared<std::string>();
    CLI::App* list = trials->add_subcommand("list", "The trials recorded in a session.");
    list->add_option("--session", *session, "session id")->required();
    list->callback([session, &context] {
      context.action = [session, &context] {
        auto client = Connect(context);
        const json items = client->GetAllPages(
            "/sessions/" + std::to_string(ParseId(*session, "session")) + "/trials", "");
        if (context.options.json) {
          context.out << items.dump(2) << "\n";
          return;
        }
        std::vector<std::vector<std::string>> rows;
        for (const api::TrialSummary& t :
             ItemsFromServer(items, &api::TrialSummaryFromJson, "trial")) {
          rows.push_back({Cell(t.id), Cell(api::OrNull(t.run_id)),
                          t.kind ? std::string(api::TrialKindName(*t.kind)) : "-",
                          Cell(t.num_samples), Cell(api::OrNull(t.duration_s())),
                          api::FormatUtc(t.created_at)});
        }
        PrintTable(context.out,
                   {"id", "run_id", "kind", "num_samples", "duration_s", "created_at_utc"}, rows);
      };
    });
  }
  {
    auto id = std::make_shared<std::string>();
    auto format = std::make_shared<std::string>("csv");
    auto out_path = std::make_shared<std::string>("-");
    CLI::App* get = trials->add_subcommand("get", "A recorded trial as CSV or OpenSim .sto.");
    get->add_option("id", *id, "trial id")->required();
    CLI::Option* format_option =
        get->add_option("--format", *format, "csv, sto (OpenSim Storage) or json")
            ->check(CLI::IsMember({"csv", "sto", "json"}));
    get->add_option("--out", *out_path, "output file ('-' for standard output, the default)");
    get->callback([id, format, format_option, out_path, &context] {
      context.action = [id, format, format_option, out_path, &context] {
        const std::int64_t trial_id = ParseId(*id, "trial");
        if (context.options.json && *out_path == "-") {
          // Machine-readable on standard output: the trial's JSON form.
          if (format_option->count() > 0 && *format != "json") {
            throw CliError::Usage("--json writes JSON: drop --format " + *format +
                                  " or write it to a file with --out FILE");
          }
          *format = "json";
        }
        auto client = Connect(context);
        const json raw = client->Get("/trials/" + std::to_string(trial_id));
        auto trial = api::TrialFromJson(raw);
        if (!trial.ok()) {
          throw CliError::Server("server sent an invalid trial: " + trial.status().ToString());
        }
        std::string text;
        if (*format == "csv") {
          text = api::TrialToCsv(*trial);
        } else if (*format == "sto") {
          text = api::TrialToSto(*trial);
        } else {
          // The server's form: the trial and, if imported, where it came from.
          json out = api::TrialToJson(*trial);
          const auto import = FromServer(api::TrialImportOf(raw), "trial");
          if (import) out.emplace("import", api::TrialImportRecordToJson(*import));
          text = out.dump() + "\n";
        }
        WriteOutput(context, *out_path, text);
        if (context.options.json && *out_path != "-") {
          PrintWritten(context, "trial_id", trial_id, *format, *out_path, text.size());
        }
      };
    });
  }
}

}  // namespace fesbench::cli
