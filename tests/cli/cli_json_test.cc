// Integration (docs/CLI.md): the CLI an analyst expects, against a real
// fesbench-server — `protocols list|show` with units, defaults and limits
// as the server states them; `--json` on every command, parsed with a JSON
// parser, including `run start` while following (one JSON object per event
// line); the token from a file or standard input; flag names that match the
// API fields (`--age-years`); validation messages naming unit and range.

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cli_runner.h"
#include "server_process.h"

namespace fesbench::testing {
namespace {

using nlohmann::json;
using ::testing::HasSubstr;
using ::testing::Not;

// stdout as one JSON document; fails the test (and returns null) otherwise.
json ParseOut(const CliRun& run, const std::string& what) {
  EXPECT_EQ(run.exit_code, 0) << what << ": " << run.err;
  const json parsed = json::parse(run.out, nullptr, false);
  EXPECT_FALSE(parsed.is_discarded()) << what << " --json is not JSON:\n" << run.out;
  return parsed.is_discarded() ? json() : parsed;
}

fs::path WriteTokenFile(const Cli& cli, const std::string& name, const std::string& text) {
  const fs::path path = cli.dir() / name;
  std::ofstream(path) << text;
  ::chmod(path.c_str(), 0600);
  return path;
}

TEST(CliJsonTest, EveryCommandAnswersJson) {
  ServerProcess server;
  auto http = server.Client();
  const std::string admin = server.admin_token();
  const json truth = Call(http, "GET", "/api/v1/bench/virtual-subject", admin).body;
  const double mass_kg = truth["anthropometrics"]["body_mass_kg"];
  const double shank_cm = truth["anthropometrics"]["shank_length_m"].get<double>() * 100.0;
  Cli cli;
  const fs::path token_file = WriteTokenFile(cli, "admin.token", admin + "\n");

  // login with the token from a file: the user it belongs to, as JSON.
  const json login = ParseOut(
      cli.Run({"login", Url(server), "--token-file", token_file.string(), "--json"}), "login");
  EXPECT_EQ(login["server"], Url(server));
  EXPECT_EQ(login["user"]["name"], "admin");
  EXPECT_EQ(login["user"]["role"], "admin");
  EXPECT_EQ(json::parse(ReadAll(login["config_file"].get<std::string>()))["token"], admin);

  // protocols: the catalogue with units, defaults and limits.
  const json catalogue = ParseOut(cli.Run({"protocols", "list", "--json"}), "protocols list");
  ASSERT_TRUE(catalogue.is_array());
  const json server_catalogue = Call(http, "GET", "/api/v1/protocols", admin).body["protocols"];
  EXPECT_EQ(catalogue, server_catalogue) << "as the server states it";
  bool has_rapid = false;
  for (const auto& p : catalogue) has_rapid |= p["name"] == "rapid_parameterisation";
  EXPECT_TRUE(has_rapid);
  auto list_text = cli.Run({"protocols", "list"});
  ASSERT_EQ(list_text.exit_code, 0) << list_text.err;
  EXPECT_THAT(list_text.out, HasSubstr("rapid_parameterisation"));
  EXPECT_THAT(list_text.out, HasSubstr("tolerance_test"));

  // subjects: --age-years as the API field; --age kept as a hidden alias.
  const json subject = ParseOut(
      cli.Run({"subjects", "create", "JS01", "--leg", "right", "--age-years", "34", "--weight-kg",
               std::to_string(mass_kg), "--shank-length-cm", std::to_string(shank_cm), "--json"}),
      "subjects create");
  EXPECT_EQ(subject["details"]["age_years"], 34);
  EXPECT_EQ(subject["code"], "JS01");
  auto create_help = cli.Run({"subjects", "create", "--help"});
  EXPECT_THAT(create_help.out, HasSubstr("--age-years"));
  EXPECT_THAT(create_help.out, Not(HasSubstr("--age ")));
  const json alias = ParseOut(cli.Run({"subjects", "create", "JS02", "--age", "50", "--json"}),
                              "subjects create --age");
  EXPECT_EQ(alias["details"]["age_years"], 50);
  const json edited = ParseOut(
      cli.Run({"subjects", "edit", "JS02", "--reason", "measured", "--age-years", "51", "--json"}),
      "subjects edit");
  EXPECT_EQ(edited["details"]["age_years"], 51);
  EXPECT_EQ(edited["revision"], 2);
  const json subjects = ParseOut(cli.Run({"subjects", "list", "--json"}), "subjects list");
  EXPECT_EQ(subjects.size(), 2u);
  const json shown = ParseOut(cli.Run({"subjects", "show", "JS02", "--json"}), "subjects show");
  EXPECT_EQ(shown["revisions"].size(), 2u);

  // sessions.
  const json session =
      ParseOut(cli.Run({"sessions", "create", "--subject", "JS01", "--leg", "right", "--date",
                        "2026-11-21", "--threshold-ma",
                        std::to_string(truth["threshold_ma"].get<double>()), "--max-tolerated-ma",
                        std::to_string(truth["max_tolerated_ma"].get<double>()), "--json"}),
               "sessions create");
  const std::string session_id = std::to_string(session["id"].get<std::int64_t>());
  EXPECT_EQ(ParseOut(cli.Run({"sessions", "list", "--subject", "JS01", "--json"}), "sessions list")
                .size(),
            1u);
  const json corrected = ParseOut(cli.Run({"sessions", "edit", session_id, "--reason", "note",
                                           "--notes", "json test", "--json"}),
                                  "sessions edit");
  EXPECT_EQ(corrected["details"]["notes"], "json test");

  // protocols show: without a session a stimulation default is its rule;
  // with --session it is resolved in mA, as GET /protocols/{name} says.
  const json general = ParseOut(cli.Run({"protocols", "show", "rapid_parameterisation", "--json"}),
                                "protocols show");
  const json resolved = ParseOut(
      cli.Run({"protocols", "show", "rapid_parameterisation", "--session", session_id, "--json"}),
      "protocols show --session");
  EXPECT_EQ(
      resolved,
      Call(http, "GET", "/api/v1/protocols/rapid_parameterisation?session_id=" + session_id, admin)
          .body);
  bool saw_rule = false;
  for (std::size_t i = 0; i < general["parameters"].size(); ++i) {
    const json& g = general["parameters"][i];
    const json& r = resolved["parameters"][i];
    for (const char* key : {"name", "unit", "min", "max"}) EXPECT_TRUE(g.contains(key)) << key;
    if (g["default"].is_null()) {
      saw_rule = true;
      EXPECT_TRUE(g["default_rule"].is_string()) << g.dump();
      EXPECT_TRUE(r["default"].is_number()) << r.dump();
    }
  }
  EXPECT_TRUE(saw_rule) << "rapid_parameterisation has session-derived defaults";
  auto show_text =
      cli.Run({"protocols", "show", "rapid_parameterisation", "--session", session_id});
  ASSERT_EQ(show_text.exit_code, 0) << show_text.err;
  EXPECT_THAT(show_text.out, HasSubstr("unit"));
  EXPECT_THAT(show_text.out, HasSubstr(" mA "));
  auto unknown = cli.Run({"protocols", "show", "no_such_protocol"});
  EXPECT_EQ(unknown.exit_code, 1);
  ExpectOneErrorLine(unknown);

  // run start --json while following: one JSON object per line.
  auto run = cli.Run({"run", "start", session_id, "rapid_parameterisation", "--json"});
  ASSERT_EQ(run.exit_code, 0) << run.out << run.err;
  EXPECT_EQ(run.err, "");
  std::vector<json> events;
  std::istringstream lines(run.out);
  for (std::string line; std::getline(lines, line);) {
    const json event = json::parse(line, nullptr, false);
    ASSERT_FALSE(event.is_discarded()) << "not a JSON line: " << line;
    ASSERT_TRUE(event.contains("event") && event.contains("run_id") && event.contains("data"))
        << line;
    events.push_back(event);
  }
  ASSERT_GE(events.size(), 4u);
  EXPECT_EQ(events.front()["event"], "started");
  const std::int64_t run_id = events.front()["run_id"];
  std::set<std::string> kinds;
  for (const auto& e : events) {
    kinds.insert(e["event"].get<std::string>());
    EXPECT_EQ(e["run_id"], run_id);
  }
  for (const char* kind : {"state", "progress", "trial", "end"}) {
    EXPECT_TRUE(kinds.contains(kind)) << "no " << kind << " event";
  }
  EXPECT_EQ(events.back()["event"], "run");
  EXPECT_EQ(events.back()["data"]["state"], "done");
  const std::string run_text = std::to_string(run_id);
  EXPECT_EQ(ParseOut(cli.Run({"run", "show", run_text, "--json"}), "run show")["state"], "done");

  // A run that is over cannot be cancelled or stopped: the server's error, one line.
  auto cancel = cli.Run({"run", "cancel", run_text, "--json"});
  EXPECT_EQ(cancel.exit_code, 1);
  ExpectOneErrorLine(cancel);

  // trials and parameter sets.
  const json trials =
      ParseOut(cli.Run({"trials", "list", "--session", session_id, "--json"}), "trials list");
  ASSERT_FALSE(trials.empty());
  const std::string trial_id = std::to_string(trials[0]["id"].get<std::int64_t>());
  const json trial = ParseOut(cli.Run({"trials", "get", trial_id, "--json"}), "trials get");
  EXPECT_TRUE(trial.contains("channels")) << trial.dump().substr(0, 200);
  EXPECT_TRUE(trial.contains("sample_rate_hz"));
  const fs::path sto = cli.dir() / "t.sto";
  const json wrote = ParseOut(
      cli.Run({"trials", "get", trial_id, "--format", "sto", "--out", sto.string(), "--json"}),
      "trials get --out");
  EXPECT_EQ(wrote["out"], sto.string());
  EXPECT_EQ(wrote["bytes"], fs::file_size(sto));
  auto conflict = cli.Run({"trials", "get", trial_id, "--format", "csv", "--json"});
  EXPECT_EQ(conflict.exit_code, 2);
  ExpectOneErrorLine(conflict);

  const json sets =
      ParseOut(cli.Run({"params", "list", "--subject", "JS01", "--from", "2000-01-01", "--json"}),
               "params list");
  ASSERT_EQ(sets.size(), 1u);
  const std::string set_id = std::to_string(sets[0]["id"].get<std::int64_t>());
  const json stored = ParseOut(cli.Run({"params", "get", set_id, "--json"}), "params get");
  EXPECT_TRUE(stored.contains("parameters"));
  EXPECT_EQ(stored["id"], sets[0]["id"]);
  const fs::path csv = cli.dir() / "p.csv";
  const json wrote_csv = ParseOut(
      cli.Run({"params", "get", set_id, "--format", "csv", "--out", csv.string(), "--json"}),
      "params get --out");
  EXPECT_EQ(wrote_csv["format"], "csv");
  EXPECT_THAT(ReadAll(csv), ::testing::StartsWith("field,value\n"));
  EXPECT_EQ(
      ParseOut(cli.Run({"params", "list", "--subject", "JS01", "--since", "2999-01-01", "--json"}),
               "params list --since")
          .size(),
      0u);

  // analysis jobs.
  const json prediction =
      ParseOut(cli.Run({"predict", "--params", set_id, "--stimulus", "step", "--json"}), "predict");
  EXPECT_EQ(prediction["parameter_set_id"].get<std::int64_t>(), std::stoll(set_id));
  const json identified = ParseOut(cli.Run({"identify", "--session", session_id, "--method",
                                            "rapid", "--passive-method", "free_swing", "--json"}),
                                   "identify");
  EXPECT_FALSE(identified["parameter_sets"].empty());

  // Data in and out (docs/API.md, "Session archives"): the wide history, the tidy curves, the
  // session archive and its import into another session, a recording.
  auto wide = cli.Run({"params", "list", "--subject", "JS01", "--format", "csv"});
  ASSERT_EQ(wide.exit_code, 0) << wide.err;
  std::istringstream wide_lines(wide.out);
  std::string header, row;
  std::getline(wide_lines, header);
  EXPECT_THAT(header, ::testing::StartsWith("parameter_set_id,subject_id,leg,version,"));
  EXPECT_THAT(header, HasSubstr("contraction.pole_per_s"));
  EXPECT_THAT(header, Not(HasSubstr("[")));  // no indexed curve points: they are in `curves`
  int set_rows = 0;
  while (std::getline(wide_lines, row)) ++set_rows;
  EXPECT_EQ(set_rows, 2);  // the run's set and the identification's
  auto curves = cli.Run({"params", "curves", set_id});
  ASSERT_EQ(curves.exit_code, 0) << curves.err;
  EXPECT_THAT(curves.out, ::testing::StartsWith("curve,x,x_unit,y,y_unit\n"));
  EXPECT_THAT(curves.out, HasSubstr("\ntau_pta,90,deg,"));
  EXPECT_THAT(curves.out, HasSubstr("\nf_atv,-400,deg/s,"));
  const json curve_points = ParseOut(cli.Run({"params", "curves", set_id, "--json"}), "curves");
  ASSERT_GT(curve_points.size(), 500u);
  EXPECT_EQ(curve_points[0]["curve"], "irc");

  const fs::path archive = cli.dir() / "s.tar.gz";
  const json exported = ParseOut(cli.Run({"sessions", "export", session_id, "--format", "tar.gz",
                                          "--out", archive.string(), "--json"}),
                                 "sessions export");
  EXPECT_EQ(exported["bytes"], fs::file_size(archive));
  const json other = ParseOut(cli.Run({"sessions", "create", "--subject", "JS02", "--leg", "right",
                                       "--date", "2026-11-22", "--json"}),
                              "sessions create");
  const std::string other_id = std::to_string(other["id"].get<std::int64_t>());
  const json imported =
      ParseOut(cli.Run({"trials", "import", "--session", other_id, archive.string(), "--json"}),
               "trials import archive");
  EXPECT_EQ(imported["trials"].size(), trials.size());
  EXPECT_EQ(imported["parameter_sets"].size(), 2u);
  auto twice = cli.Run({"trials", "import", "--session", other_id, archive.string()});
  EXPECT_EQ(twice.exit_code, 1);
  ExpectOneErrorLine(twice);
  EXPECT_THAT(twice.err, HasSubstr("HTTP 409"));
  const fs::path recording = cli.dir() / "rig.csv";
  std::ofstream(recording) << "Time (ms),Knee (rad),I (A)\n0,1.5,0\n5,1.51,0.02\n10,1.52,0.02\n";
  const json one =
      ParseOut(cli.Run({"trials", "import", "--session", other_id, recording.string(), "--kind",
                        "prediction_step", "--time-column", "Time (ms)", "--time-unit", "ms",
                        "--map", "Knee (rad)=angle_deg:rad", "--map", "I (A)=stim_ma:A", "--json"}),
               "trials import csv");
  ASSERT_EQ(one["trials"].size(), 1u);
  const json back =
      ParseOut(cli.Run({"trials", "get", std::to_string(one["trials"][0]["id"].get<std::int64_t>()),
                        "--json"}),
               "trials get imported");
  EXPECT_EQ(back["import"]["source"], "rig.csv");
  auto refused = cli.Run({"trials", "import", "--session", other_id, recording.string(), "--kind",
                          "prediction_step", "--time-column", "Time (ms)", "--map",
                          "Knee (rad)=angle_deg:rad", "--map", "I (A)=stim_ma:A"});
  EXPECT_EQ(refused.exit_code, 1);
  ExpectOneErrorLine(refused);
  EXPECT_THAT(refused.err, HasSubstr("is the time unit right"));

  const fs::path report_path = cli.dir() / "r.html";
  const json report =
      ParseOut(cli.Run({"report", session_id, "--out", report_path.string(), "--json"}), "report");
  EXPECT_EQ(report["bytes"], fs::file_size(report_path));
  EXPECT_THAT(ReadAll(report_path), HasSubstr("Runs and their outcomes"));

  // e-stop and its clear.
  EXPECT_EQ(ParseOut(cli.Run({"estop", "--json"}), "estop")["estopped"], true);
  EXPECT_EQ(ParseOut(cli.Run({"estop", "--clear", "--json"}), "estop --clear")["estopped"], false);

  // The server's range message names the field, its unit and the range.
  auto bad = cli.Run({"subjects", "create", "JS03", "--weight-kg", "-5"});
  EXPECT_EQ(bad.exit_code, 1);
  ExpectOneErrorLine(bad);
  EXPECT_THAT(bad.err, HasSubstr("weight_kg must be 1–400 kg, got -5"));
  EXPECT_THAT(bad.err, HasSubstr("details.weight_kg"));
}

TEST(CliJsonTest, TokenFromAFileOrStandardInput) {
  ServerProcess server;
  const std::string admin = server.admin_token();
  Cli cli;
  const std::string url = Url(server);

  // Without login: --server and --token-file (trailing newline dropped).
  const fs::path file = WriteTokenFile(cli, "t", "  " + admin + "\n\n");
  const json me = ParseOut(
      cli.Run({"--server", url, "--token-file", file.string(), "subjects", "list", "--json"}),
      "--token-file");
  EXPECT_EQ(me, json::array());
  // The file wins over FESBENCH_TOKEN.
  auto over_env =
      cli.Run({"--server", url, "--token-file", file.string(), "subjects", "list"}, "fsb_wrong");
  EXPECT_EQ(over_env.exit_code, 0) << over_env.err;

  // From standard input.
  auto piped = cli.RunWithInput(
      {"--server", url, "--token-file", "-", "subjects", "create", "TK01", "--json"}, admin + "\n");
  EXPECT_EQ(ParseOut(piped, "--token-file -")["code"], "TK01");
  auto login = cli.RunWithInput({"login", url, "--token", "-"}, admin + "\n");
  ASSERT_EQ(login.exit_code, 0) << login.err;
  EXPECT_THAT(login.out, HasSubstr("as admin (admin)"));
  EXPECT_EQ(json::parse(ReadAll(cli.config_file()))["token"], admin);

  // A wrong token in the file: the server refuses it (1); an empty file,
  // a missing one or empty input is a usage error (2); one line each.
  const fs::path wrong = WriteTokenFile(cli, "wrong", "fsb_not_a_token\n");
  auto refused = cli.Run({"--server", url, "--token-file", wrong.string(), "subjects", "list"});
  EXPECT_EQ(refused.exit_code, 1);
  ExpectOneErrorLine(refused);
  const fs::path empty = WriteTokenFile(cli, "empty", "\n");
  for (const auto& args : std::vector<std::vector<std::string>>{
           {"--server", url, "--token-file", empty.string(), "subjects", "list"},
           {"--server", url, "--token-file", (cli.dir() / "missing").string(), "subjects", "list"},
           {"login", url}}) {
    auto failed = cli.RunWithInput(args, "");
    EXPECT_EQ(failed.exit_code, 2) << ::testing::PrintToString(args) << failed.err;
    ExpectOneErrorLine(failed);
  }
  auto no_input = cli.RunWithInput({"login", url, "--token", "-"}, "");
  EXPECT_EQ(no_input.exit_code, 2);
  EXPECT_THAT(no_input.err, HasSubstr("no token on standard input"));
}

}  // namespace
}  // namespace fesbench::testing
