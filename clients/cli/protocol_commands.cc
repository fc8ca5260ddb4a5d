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

#include "api/protocol_info.h"
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
std::string Value(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.10g", value);
  return buffer;
}

// "default" cell: the value in its unit, else the rule the server gives.
std::string DefaultCell(const api::ProtocolParameterInfo& p) {
  if (p.default_value) return Value(*p.default_value);
  return p.default_rule ? "(" + *p.default_rule + ")" : "-";
}

void PrintProtocol(CliContext& context, const api::ProtocolInfo& protocol) {
  context.out << protocol.name << " (version " << protocol.version << "): " << protocol.title
              << "\n"
              << "thesis section: " << protocol.thesis_section << "\n"
              << "stimulates: " << (protocol.stimulates ? "yes" : "no") << "\n"
              << "bench mode: " << protocol.bench_mode << "\n"
              << "min rest: " << Cell(json(protocol.min_rest_s)) << " s\n";
  if (!protocol.description.empty()) context.out << protocol.description << "\n";
  std::vector<std::vector<std::string>> rows;
  for (const api::ProtocolParameterInfo& p : protocol.parameters) {
    rows.push_back({p.name, p.unit, DefaultCell(p), Value(p.min),
                    Value(p.max), p.integer ? "integer" : "number", p.advanced ? "advanced" : "",
                    p.label});
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
        const std::vector<api::ProtocolInfo> catalogue = FromServer(
            api::ProtocolCatalogueFromJson(client->Get("/protocols" + SessionQuery(*session))),
            "protocol catalogue");
        if (context.options.json) {
          json items = json::array();
          for (const api::ProtocolInfo& p : catalogue) items.push_back(api::ProtocolInfoToJson(p));
          context.out << items.dump(2) << "\n";
          return;
        }
        std::vector<std::vector<std::string>> rows;
        for (const api::ProtocolInfo& p : catalogue) {
          rows.push_back({p.name, p.thesis_section, p.stimulates ? "yes" : "no", p.bench_mode,
                          std::to_string(p.parameters.size()), p.title});
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
        PrintProtocol(context, FromServer(api::ProtocolInfoFromJson(protocol), "protocol"));
      };
    });
  }
}

}  // namespace fesbench::cli
