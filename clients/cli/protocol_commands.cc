// `fesbench protocols list|show`: what can be run, and with which parameters
// — their units, defaults and limits exactly as the server states them in
// GET /protocols[/NAME][?session_id=N] (docs/PROTOCOLS.md). With --session
// the defaults are resolved for that session (its threshold, max tolerated
// amplitude and range of motion); without, a session-derived default is
// shown as its rule.

#include <cstdio>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "clients/cli/commands.h"
#include "clients/cli/output.h"

namespace fesbench::cli {

namespace {

using nlohmann::json;

std::string SessionQuery(const std::string& session) {
  return session.empty() ? "" : "?session_id=" + std::to_string(ParseId(session, "--session"));
}

// A limit or default as the server states it (up to 10 digits, so that
// e.g. a seed's 4294967295 is not rounded).
std::string Value(const json& value) {
  if (!value.is_number()) return Cell(value);
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.10g", value.get<double>());
  return buffer;
}

// "default" cell: the value in its unit, else the rule the server gives.
std::string DefaultCell(const json& p) {
  const json def = p.value("default", json(nullptr));
  if (!def.is_null()) return Value(def);
  const json rule = p.value("default_rule", json(nullptr));
  return rule.is_string() ? "(" + rule.get<std::string>() + ")" : "-";
}

void PrintProtocol(CliContext& context, const json& protocol) {
  context.out << Cell(protocol["name"]) << " (version " << Cell(protocol.value("version", json()))
              << "): " << Cell(protocol.value("title", json())) << "\n"
              << "thesis section: " << Cell(protocol.value("thesis_section", json())) << "\n"
              << "stimulates: " << Cell(protocol.value("stimulates", json())) << "\n"
              << "bench mode: " << Cell(protocol.value("bench_mode", json())) << "\n"
              << "min rest: " << Cell(protocol.value("min_rest_s", json())) << " s\n";
  const std::string description = protocol.value("description", "");
  if (!description.empty()) context.out << description << "\n";
  std::vector<std::vector<std::string>> rows;
  for (const auto& p : protocol.value("parameters", json::array())) {
    rows.push_back({Cell(p["name"]), Cell(p.value("unit", json(nullptr))), DefaultCell(p),
                    Value(p.value("min", json(nullptr))), Value(p.value("max", json(nullptr))),
                    p.value("integer", false) ? "integer" : "number",
                    p.value("advanced", false) ? "advanced" : "", Cell(p.value("label", ""))});
  }
  context.out << "parameters (--param NAME=VALUE in the unit shown):\n";
  PrintTable(context.out, {"name", "unit", "default", "min", "max", "type", "", "label"}, rows);
}

}  // namespace

void RegisterProtocolCommands(CLI::App& app, CliContext& context) {
  CLI::App* protocols =
      app.add_subcommand("protocols", "The protocol catalogue: list, show (parameters, units).");
  protocols->require_subcommand(1);
  {
    auto session = std::make_shared<std::string>();
    CLI::App* list = protocols->add_subcommand("list", "Every protocol the server can run.");
    list->add_option("--session", *session,
                     "session id: resolve the defaults for this session (with --json)");
    list->callback([session, &context] {
      context.action = [session, &context] {
        auto client = Connect(context);
        const json catalogue = client->Get("/protocols" + SessionQuery(*session));
        const json items = catalogue.value("protocols", json::array());
        if (context.options.json) {
          context.out << items.dump(2) << "\n";
          return;
        }
        std::vector<std::vector<std::string>> rows;
        for (const auto& p : items) {
          rows.push_back({Cell(p["name"]), Cell(p.value("thesis_section", json(nullptr))),
                          Cell(p.value("stimulates", json(nullptr))),
                          Cell(p.value("bench_mode", json(nullptr))),
                          std::to_string(p.value("parameters", json::array()).size()),
                          Cell(p.value("title", json(nullptr)))});
        }
        PrintTable(context.out,
                   {"name", "thesis_section", "stimulates", "bench_mode", "parameters", "title"},
                   rows);
      };
    });
  }
  {
    auto name = std::make_shared<std::string>();
    auto session = std::make_shared<std::string>();
    CLI::App* show = protocols->add_subcommand(
        "show", "One protocol: its parameters with units, defaults and limits.");
    show->add_option("name", *name, "protocol name, e.g. rapid_parameterisation")->required();
    show->add_option("--session", *session,
                     "session id: defaults resolved for this session (threshold, max tolerated, "
                     "range of motion)");
    show->callback([name, session, &context] {
      context.action = [name, session, &context] {
        auto client = Connect(context);
        const json protocol =
            client->Get("/protocols/" + UrlEncode(*name) + SessionQuery(*session));
        if (context.options.json) {
          context.out << protocol.dump(2) << "\n";
          return;
        }
        PrintProtocol(context, protocol);
      };
    });
  }
}

}  // namespace fesbench::cli
