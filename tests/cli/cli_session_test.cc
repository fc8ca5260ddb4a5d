// Integration: the `fesbench` binary against a real fesbench-server (issue
// 9): a whole analyst session — login (config file mode 0600), lists,
// subjects and sessions, rapid_parameterisation followed with --follow while
// piped, parameter sets as JSON and CSV, a trial as OpenSim .sto, predict,
// identify, compare — checking outputs and exit codes; then bad usage (2),
// server errors (1, the server's message) and an unreachable server (3).

#include <fcntl.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "api/parameter_set_json.h"
#include "api/trial.h"
#include "cli_runner.h"
#include "clients/cli/cli.h"
#include "clients/cli/config.h"
#include "server_process.h"

namespace fesbench::testing {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::testing::AnyOf;
using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

TEST(CliSessionTest, WholeAnalystSession) {
  ServerProcess server;
  auto http = server.Client();
  const std::string admin = server.admin_token();
  auto truth = Call(http, "GET", "/api/v1/bench/virtual-subject", admin);
  ASSERT_EQ(truth.status, 200) << truth.text;
  const double mass_kg = truth.body["anthropometrics"]["body_mass_kg"];
  const double shank_cm = truth.body["anthropometrics"]["shank_length_m"].get<double>() * 100.0;
  const std::string threshold = std::to_string(truth.body["threshold_ma"].get<double>());
  const std::string max_ma = std::to_string(truth.body["max_tolerated_ma"].get<double>());
  Cli cli;

  // Login: the config file holds server and token, mode 0600.
  auto login = cli.Run({"login", Url(server), "--token", admin});
  ASSERT_EQ(login.exit_code, 0) << login.err;
  EXPECT_THAT(login.out, HasSubstr("logged in to " + Url(server)));
  struct stat st {};
  ASSERT_EQ(::stat(cli.config_file().c_str(), &st), 0) << cli.config_file();
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  const json config = json::parse(ReadAll(cli.config_file()));
  EXPECT_EQ(config["server"], Url(server));
  EXPECT_EQ(config["token"], admin);

  // Empty lists, as a table and as JSON.
  auto empty = cli.Run({"subjects", "list"});
  ASSERT_EQ(empty.exit_code, 0) << empty.err;
  EXPECT_THAT(empty.out, StartsWith("id  code  legs"));
  auto empty_json = cli.Run({"subjects", "list", "--json"});
  ASSERT_EQ(empty_json.exit_code, 0);
  EXPECT_EQ(json::parse(empty_json.out), json::array());

  // Two subjects, one session each, two rapid runs per session (two fits
  // per leg for the comparison), each followed with --follow while piped.
  std::vector<std::int64_t> sessions, first_sets, second_sets, rb_trials, ramp_trials;
  for (const std::string code : {"CLI-A", "CLI-B"}) {
    auto subject =
        cli.Run({"subjects", "create", code, "--leg", "right", "--weight-kg",
                 std::to_string(mass_kg), "--shank-length-cm", std::to_string(shank_cm)});
    ASSERT_EQ(subject.exit_code, 0) << subject.err;
    EXPECT_THAT(subject.out, HasSubstr("created subject"));
    auto session =
        cli.Run({"sessions", "create", "--subject", code, "--leg", "right", "--date", "2026-11-21",
                 "--threshold-ma", threshold, "--max-tolerated-ma", max_ma});
    ASSERT_EQ(session.exit_code, 0) << session.err;
    const std::int64_t session_id = LastNumber(session.out, "created session");
    ASSERT_GT(session_id, 0) << session.out;
    sessions.push_back(session_id);
    for (int fit = 0; fit < 2; ++fit) {
      auto run = cli.Run(
          {"run", "start", std::to_string(session_id), "rapid_parameterisation", "--follow"});
      ASSERT_EQ(run.exit_code, 0) << run.out << run.err;
      EXPECT_EQ(run.err, "");
      EXPECT_THAT(run.out, HasSubstr("state running\n"));
      EXPECT_THAT(run.out, HasSubstr("progress 100% "));
      EXPECT_THAT(run.out, HasSubstr("trial rapid_active_random_binary stored as trial "));
      EXPECT_THAT(run.out, Not(HasSubstr("\r"))) << "no progress bar when piped";
      EXPECT_THAT(run.out, Not(HasSubstr("#"))) << "no progress bar when piped";
      const std::int64_t set_id = LastNumber(run.out, "end done parameter_set");
      ASSERT_GT(set_id, 0) << run.out;
      (fit == 0 ? first_sets : second_sets).push_back(set_id);
      if (fit == 0) {
        rb_trials.push_back(LastNumber(run.out, "rapid_active_random_binary stored as trial"));
        ramp_trials.push_back(LastNumber(run.out, "rapid_isometric_ramp_irc stored as trial"));
      }
    }
  }

  // Lists and show.
  auto subjects = cli.Run({"subjects", "list", "--json"});
  ASSERT_EQ(subjects.exit_code, 0);
  ASSERT_EQ(json::parse(subjects.out).size(), 2u);
  auto shown = cli.Run({"sessions", "show", std::to_string(sessions[0])});
  ASSERT_EQ(shown.exit_code, 0) << shown.err;
  EXPECT_THAT(shown.out, HasSubstr("rapid_parameterisation"));
  EXPECT_THAT(shown.out, HasSubstr("rapid_free_swing_passive"));
  auto run_show = cli.Run({"run", "show", "1", "--json"});
  ASSERT_EQ(run_show.exit_code, 0) << run_show.err;
  EXPECT_EQ(json::parse(run_show.out)["state"], "done");

  // Parameter-set history as a table, filtered by leg and date.
  auto history =
      cli.Run({"params", "list", "--subject", "CLI-A", "--leg", "right", "--since", "2000-01-01"});
  ASSERT_EQ(history.exit_code, 0) << history.err;
  EXPECT_THAT(history.out, StartsWith("id  leg    version  model"));  // right/left, not ids
  EXPECT_EQ(std::count(history.out.begin(), history.out.end(), '\n'), 3) << history.out;
  auto history_json = cli.Run({"params", "list", "--subject", "CLI-A", "--json"});
  ASSERT_EQ(history_json.exit_code, 0);
  EXPECT_EQ(json::parse(history_json.out)[0]["id"], first_sets[0]);
  // Which set gates stimulation (docs/SAFETY.md): each rapid run's set is
  // approved by its run, so the leg's approved set is the second run's.
  EXPECT_EQ(json::parse(history_json.out)[0]["approved"], false);
  EXPECT_EQ(json::parse(history_json.out)[1]["approved"], true);
  EXPECT_THAT(history.out, HasSubstr("approved"));
  EXPECT_THAT(history.out, HasSubstr("earlier (admin "));
  EXPECT_THAT(history.out, HasSubstr("yes (admin "));
  // A clinician's approval switches it back, and again; a blank note or
  // approving the approved set is refused.
  const std::string first = std::to_string(first_sets[0]);
  auto approved = cli.Run({"params", "approve", first, "--note", "day 1 fits the swing better"});
  ASSERT_EQ(approved.exit_code, 0) << approved.err;
  EXPECT_THAT(approved.out, HasSubstr("parameter set " + first + " approved for leg"));
  EXPECT_THAT(approved.out, HasSubstr(": yes (admin "));
  auto twice = cli.Run({"params", "approve", first, "--note", "again"});
  EXPECT_NE(twice.exit_code, 0);
  EXPECT_THAT(twice.err, HasSubstr("already is its leg's approved set"));
  auto blank = cli.Run({"params", "approve", std::to_string(second_sets[0]), "--note", " "});
  EXPECT_NE(blank.exit_code, 0);
  EXPECT_THAT(blank.err, HasSubstr("note"));
  auto relisted = cli.Run({"params", "list", "--subject", "CLI-A", "--json"});
  ASSERT_EQ(relisted.exit_code, 0);
  EXPECT_EQ(json::parse(relisted.out)[0]["approved"], true);
  EXPECT_EQ(json::parse(relisted.out)[0]["approval"]["note"], "day 1 fits the swing better");
  ASSERT_EQ(
      cli.Run({"params", "approve", std::to_string(second_sets[0]), "--note", "back"}).exit_code,
      0);

  // The model check: no prediction protocol ran on this leg, so nothing is
  // left to judge the set on, and the answer says what to run.
  auto checked = cli.Run({"params", "check", std::to_string(second_sets[0])});
  ASSERT_EQ(checked.exit_code, 0) << checked.err;
  EXPECT_THAT(checked.out, HasSubstr(": no_fresh_trials\n"));
  EXPECT_THAT(checked.out, HasSubstr("run a prediction protocol"));
  EXPECT_NE(cli.Run({"params", "check", "9999"}).exit_code, 0);

  // A parameter set as JSON (reads back as the wire type) and as CSV.
  auto params_json = cli.Run({"params", "get", std::to_string(first_sets[0]), "--format", "json"});
  ASSERT_EQ(params_json.exit_code, 0) << params_json.err;
  auto parsed = api::ParameterSetFromJson(json::parse(params_json.out));
  ASSERT_TRUE(parsed.ok()) << parsed.status().ToString();
  const double pole = json::parse(params_json.out)["contraction"]["pole_per_s"];
  EXPECT_GT(pole, 0.0);
  const fs::path csv_path = cli.dir() / "params.csv";
  auto params_csv = cli.Run({"params", "get", std::to_string(first_sets[0]), "--format", "csv",
                             "--out", csv_path.string()});
  ASSERT_EQ(params_csv.exit_code, 0) << params_csv.err;
  const std::string csv = ReadAll(csv_path);
  EXPECT_THAT(csv, StartsWith("field,value\n"));
  EXPECT_THAT(csv, HasSubstr("\ncontraction.pole_per_s," + json(pole).dump() + "\n"));
  EXPECT_THAT(csv, HasSubstr("\nprovenance.id," + std::to_string(first_sets[0]) + "\n"));

  // A trial as OpenSim .sto: header, then as many rows as the CSV export.
  const fs::path sto_path = cli.dir() / "rb.sto";
  auto sto = cli.Run({"trials", "get", std::to_string(rb_trials[0]), "--format", "sto", "--out",
                      sto_path.string()});
  ASSERT_EQ(sto.exit_code, 0) << sto.err;
  auto trial_csv = cli.Run({"trials", "get", std::to_string(rb_trials[0]), "--format", "csv"});
  ASSERT_EQ(trial_csv.exit_code, 0);
  auto trial = api::TrialFromCsv(trial_csv.out);
  ASSERT_TRUE(trial.ok()) << trial.status().ToString();
  const std::string sto_text = ReadAll(sto_path);
  EXPECT_THAT(sto_text, StartsWith("rapid_active_random_binary\nversion=1\n"));
  EXPECT_THAT(sto_text, HasSubstr("nRows=" + std::to_string(trial->num_samples()) + "\n"));
  EXPECT_THAT(sto_text, HasSubstr("endheader\ntime\t"));

  // Predict the recorded random-binary trial: errors against it, and the
  // predicted trajectory as CSV of the same length.
  const fs::path prediction_csv = cli.dir() / "prediction.csv";
  auto predict = cli.Run({"predict", "--params", std::to_string(first_sets[0]), "--stimulus",
                          std::to_string(rb_trials[0]), "--out", prediction_csv.string()});
  ASSERT_EQ(predict.exit_code, 0) << predict.err;
  std::smatch errors;
  ASSERT_TRUE(std::regex_search(predict.out, errors,
                                std::regex(R"(E_RMS ([0-9.]+) deg  E_ABS ([0-9.]+) deg)")))
      << predict.out;
  const double e_rms = std::stod(errors[1]);
  const double e_abs = std::stod(errors[2]);
  EXPECT_GT(e_rms, 0.0);
  EXPECT_LT(e_rms, 5.0) << "the rapid fit predicts its own random-binary trial (§7.4.1)";
  EXPECT_LE(e_abs, e_rms + 1e-3) << "mean absolute error never exceeds the RMS error";
  auto predicted = api::ReadTrialCsvFile(prediction_csv);
  ASSERT_TRUE(predicted.ok()) << predicted.status().ToString();
  EXPECT_EQ(predicted->num_samples(), trial->num_samples());
  EXPECT_NE(predicted->Values("angle_deg"), nullptr);
  auto step = cli.Run({"predict", "--params", std::to_string(first_sets[0]), "--stimulus", "step"});
  ASSERT_EQ(step.exit_code, 0) << step.err;
  EXPECT_THAT(step.out, HasSubstr("no measured trial"));
  // The isometric ramp trial with the §6.1.2 best-fit scale.
  auto iso = cli.Run({"predict", "--params", std::to_string(first_sets[0]), "--stimulus",
                      std::to_string(ramp_trials[0]), "--fit-scale"});
  ASSERT_EQ(iso.exit_code, 0) << iso.err;
  EXPECT_THAT(iso.out, HasSubstr(" N.m  E_ABS "));
  std::smatch scale;
  ASSERT_TRUE(std::regex_search(iso.out, scale, std::regex(R"(fitted scale ([0-9.]+) )")))
      << iso.out;
  EXPECT_NEAR(std::stod(scale[1]), 1.0, 0.3) << "the rapid set's own ramp trial";
  auto not_iso = cli.Run({"predict", "--params", std::to_string(first_sets[0]), "--stimulus",
                          std::to_string(rb_trials[0]), "--fit-scale"});
  EXPECT_EQ(not_iso.exit_code, 1);
  EXPECT_THAT(not_iso.err, HasSubstr("fit_scale"));

  // A refit of the first session's trials by the rapid method.
  auto identify = cli.Run({"identify", "--session", std::to_string(sessions[0]), "--method",
                           "rapid", "--passive-method", "free_swing"});
  ASSERT_EQ(identify.exit_code, 0) << identify.err;
  EXPECT_THAT(identify.out, HasSubstr("(version 3, model full)"));
  EXPECT_THAT(identify.out, HasSubstr("fit_rms:"));
  // Every flag reaches the request: the rapid method refuses a thesis
  // passive method instead of ignoring it.
  auto ignored = cli.Run({"identify", "--session", std::to_string(sessions[0]), "--method",
                          "rapid", "--passive-method", "simultaneous"});
  EXPECT_EQ(ignored.exit_code, 1) << ignored.out;
  ExpectOneErrorLine(ignored);
  EXPECT_THAT(ignored.err, HasSubstr("(field passive_method) [HTTP 400]"));
  auto irc = cli.Run({"identify", "--session", std::to_string(sessions[0]), "--method", "rapid",
                      "--irc-method", "step"});
  EXPECT_EQ(irc.exit_code, 1);
  EXPECT_THAT(irc.err, HasSubstr("(field irc_method) [HTTP 400]"));

  // Two sets of one leg over the trials neither was fitted on (two fresh
  // prediction runs): one pair per trial, a paired t-test over them.
  std::vector<std::int64_t> fresh;
  for (const std::string protocol : {"prediction_random_binary", "prediction_step"}) {
    auto run = cli.Run({"run", "start", std::to_string(sessions[0]), protocol, "--json"});
    ASSERT_EQ(run.exit_code, 0) << run.err;
    std::istringstream lines(run.out);
    for (std::string line; std::getline(lines, line);) {
      const json event = json::parse(line);
      if (event["event"] == "trial") fresh.push_back(event["data"]["trial_id"]);
    }
  }
  ASSERT_EQ(fresh.size(), 2u);
  const std::string set_a = std::to_string(first_sets[0]);
  const std::string set_b = std::to_string(second_sets[0]);
  auto two_sets = cli.Run({"compare", "--params-a", set_a, "--params-b", set_b, "--json"});
  ASSERT_EQ(two_sets.exit_code, 0) << two_sets.err;
  const json over_trials = json::parse(two_sets.out);
  ASSERT_EQ(over_trials["pairs"].size(), 2u);
  std::vector<std::int64_t> compared;
  for (const auto& pair : over_trials["pairs"]) {
    EXPECT_EQ(pair["a_parameter_set_id"], first_sets[0]);
    ASSERT_EQ(pair["trials"].size(), 1u);
    compared.push_back(pair["trials"][0]["trial_id"]);
  }
  EXPECT_EQ(compared, fresh) << "the trials neither set was fitted on, one pair each";
  EXPECT_EQ(over_trials["t_test"]["n"], 2);
  EXPECT_TRUE(over_trials["t_test_note"].is_null());
  auto one_trial = cli.Run({"compare", "--params-a", set_a, "--params-b", set_b, "--trials",
                            std::to_string(fresh[0])});
  ASSERT_EQ(one_trial.exit_code, 0) << one_trial.err;
  EXPECT_THAT(one_trial.out, HasSubstr("metric e_rms (deg)"));
  EXPECT_THAT(one_trial.out, HasSubstr("no paired t-test: it needs at least 2 pairs, got 1"));
  EXPECT_THAT(one_trial.out, Not(HasSubstr("paired t-test:\n")));
  auto training = cli.Run({"compare", "--params-a", set_a, "--params-b", set_b, "--trials",
                           std::to_string(rb_trials[0])});
  ASSERT_EQ(training.exit_code, 0) << training.err;
  EXPECT_THAT(training.err, HasSubstr("is a training trial of parameter set " + set_a));

  // Compare the first and second fits of each leg: a paired t-test, n = 2.
  const std::string a = std::to_string(first_sets[0]) + "," + std::to_string(first_sets[1]);
  const std::string b = std::to_string(second_sets[0]) + "," + std::to_string(second_sets[1]);
  auto compare = cli.Run({"compare", "--params-a", a, "--params-b", b});
  ASSERT_EQ(compare.exit_code, 0) << compare.err;
  EXPECT_THAT(compare.out, HasSubstr("metric e_rms (deg)"));
  EXPECT_THAT(compare.out, HasSubstr("paired t-test:\nn  mean_diff"));
  auto compare_json = cli.Run({"compare", "--params-a", a, "--params-b", b, "--json"});
  ASSERT_EQ(compare_json.exit_code, 0) << compare_json.err;
  const json t_test = json::parse(compare_json.out)["t_test"];
  EXPECT_EQ(t_test["n"], 2);
  EXPECT_EQ(t_test["df"], 1);
  EXPECT_THAT(compare.out, HasSubstr(std::to_string(t_test["n"].get<int>()) + "  "));

  // E-stop latches and clears.
  auto estop = cli.Run({"estop"});
  ASSERT_EQ(estop.exit_code, 0) << estop.err;
  EXPECT_THAT(estop.out, HasSubstr("estopped: yes"));
  auto refused = cli.Run({"run", "start", std::to_string(sessions[0]), "rapid_parameterisation"});
  EXPECT_EQ(refused.exit_code, 1) << "a latched e-stop refuses runs";
  ExpectOneErrorLine(refused);
  auto clear = cli.Run({"estop", "--clear"});
  ASSERT_EQ(clear.exit_code, 0) << clear.err;
  EXPECT_THAT(clear.out, HasSubstr("estopped: no"));

  EXPECT_EQ(server.Terminate(), 0);
}

TEST(CliSessionTest, ExitCodesAndOneLineErrors) {
  ServerProcess server;
  auto http = server.Client();
  const std::string analyst = CreateUserToken(http, server.admin_token(), "ana", "analyst");
  Cli cli;

  // No server configured yet: a usage error.
  auto unconfigured = cli.Run({"subjects", "list"});
  EXPECT_EQ(unconfigured.exit_code, 2);
  ExpectOneErrorLine(unconfigured);
  EXPECT_THAT(unconfigured.err, HasSubstr("fesbench login"));

  ASSERT_EQ(cli.Run({"login", Url(server), "--token", analyst}).exit_code, 0);

  // Usage errors: exit 2, one clear line, nothing on stdout.
  const std::vector<std::pair<std::vector<std::string>, std::string>> usage = {
      {{"frobnicate"}, "unknown command 'frobnicate'"},
      {{"params", "get", "abc"}, "parameter set must be a positive integer id"},
      {{"params", "get", "1", "--format", "xml"}, "--format"},
      {{"params", "list"}, "--subject"},
      {{"trials", "get", "1", "--format", "sto", "--bogus"}, "--bogus"},
      {{"run", "start", "1", "rapid_parameterisation", "--param", "amplitude_ma"}, "key=value"},
      {{"compare", "--params-a", "1,2", "--params-b", "3"}, "same number"},
      {{"login", "ftp://x", "--token", "t"}, "server URL must be"},
  };
  for (const auto& [args, message] : usage) {
    auto run = cli.Run(args);
    EXPECT_EQ(run.exit_code, 2) << args[0] << ": " << run.err;
    ExpectOneErrorLine(run);
    EXPECT_THAT(run.err, HasSubstr(message));
    EXPECT_EQ(run.out, "");
  }

  // Errors reported by the server: exit 1 with its message.
  auto unknown = cli.Run({"params", "get", "999"});
  EXPECT_EQ(unknown.exit_code, 1);
  ExpectOneErrorLine(unknown);
  EXPECT_THAT(unknown.err, HasSubstr("parameter set 999 not found [HTTP 404]"));
  auto unknown_trial = cli.Run({"trials", "get", "77", "--format", "csv"});
  EXPECT_EQ(unknown_trial.exit_code, 1);
  EXPECT_THAT(unknown_trial.err, HasSubstr("[HTTP 404]"));
  auto forbidden = cli.Run({"subjects", "create", "NOPE"});
  EXPECT_EQ(forbidden.exit_code, 1) << "an analyst may not create subjects";
  EXPECT_THAT(forbidden.err, HasSubstr("[HTTP 403]"));
  auto bad_token = cli.Run({"subjects", "list"}, "fsb_not_a_token");
  EXPECT_EQ(bad_token.exit_code, 1) << "FESBENCH_TOKEN overrides the stored token";
  EXPECT_THAT(bad_token.err, HasSubstr("[HTTP 401]"));
  auto failed_job = cli.Run({"identify", "--session", "5"});
  EXPECT_EQ(failed_job.exit_code, 1);
  ExpectOneErrorLine(failed_job);

  // The server cannot be reached: exit 3 (--server overrides the config).
  const int port = server.port();
  EXPECT_EQ(server.Terminate(), 0);
  auto gone = cli.Run({"subjects", "list"});
  EXPECT_EQ(gone.exit_code, 3);
  ExpectOneErrorLine(gone);
  EXPECT_THAT(gone.err, HasSubstr("cannot reach http://127.0.0.1:" + std::to_string(port)));
  auto elsewhere = cli.Run({"--server", "http://127.0.0.1:1", "params", "get", "1"});
  EXPECT_EQ(elsewhere.exit_code, 3);
  EXPECT_THAT(elsewhere.err, HasSubstr("cannot reach http://127.0.0.1:1:"));
}

// An admin issues and revokes analysts' tokens from the command line; a
// token's secret is shown once (or written to a new 0600 file).
TEST(CliSessionTest, AdminIssuesAndRevokesTokens) {
  ServerProcess server;
  auto http = server.Client();
  Cli cli;
  ASSERT_EQ(cli.Run({"login", Url(server), "--token", server.admin_token()}).exit_code, 0);

  auto created = cli.Run({"users", "create", "ana", "--role", "analyst", "--token", "--label",
                          "laptop"});
  ASSERT_EQ(created.exit_code, 0) << created.err;
  EXPECT_THAT(created.out, HasSubstr("(analyst)"));
  EXPECT_THAT(created.out, HasSubstr("shown once"));
  std::smatch secret;
  ASSERT_TRUE(std::regex_search(created.out, secret, std::regex("\n(fsb_[A-Za-z0-9_-]+)\n")))
      << created.out;
  const std::string token = secret[1];
  auto me = Call(http, "GET", "/api/v1/me", token);
  ASSERT_EQ(me.status, 200);
  EXPECT_EQ(me.body["role"], "analyst");

  const fs::path file = cli.dir() / "ana.token";
  auto issued = cli.Run({"users", "issue-token", "ana", "--expires-in-s", "3600", "--out",
                         file.string()});
  ASSERT_EQ(issued.exit_code, 0) << issued.err;
  EXPECT_THAT(issued.out, Not(HasSubstr("fsb_"))) << "the secret goes to the file only";
  struct stat st {};
  ASSERT_EQ(::stat(file.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  std::string second = ReadAll(file);
  second.pop_back();  // the newline
  EXPECT_EQ(Call(http, "GET", "/api/v1/me", second).status, 200);
  auto again = cli.Run({"users", "issue-token", "ana", "--out", file.string()});
  EXPECT_EQ(again.exit_code, 1) << "an existing file is never overwritten";
  EXPECT_THAT(again.err, HasSubstr("never overwritten"));
  auto no_folder = cli.Run({"users", "issue-token", "ana", "--out",
                            (cli.dir() / "missing" / "t").string()});
  EXPECT_EQ(no_folder.exit_code, 1) << "no token is issued that could not be kept";

  auto tokens = cli.Run({"users", "tokens", "--user", "ana", "--json"});
  ASSERT_EQ(tokens.exit_code, 0) << tokens.err;
  const json listed = json::parse(tokens.out);
  ASSERT_EQ(listed.size(), 2u) << "refused --out files issued no token";
  EXPECT_EQ(listed[0]["label"], "laptop");
  EXPECT_THAT(tokens.out, Not(HasSubstr("fsb_"))) << "a listed token has no secret";
  auto revoked = cli.Run({"users", "revoke-token", listed[0]["id"].dump()});
  ASSERT_EQ(revoked.exit_code, 0) << revoked.err;
  EXPECT_EQ(Call(http, "GET", "/api/v1/me", token).status, 401);
  EXPECT_EQ(Call(http, "GET", "/api/v1/me", second).status, 200);

  auto users = cli.Run({"users", "list"});
  ASSERT_EQ(users.exit_code, 0);
  EXPECT_TRUE(std::regex_search(users.out, std::regex("\n2 +ana +analyst +yes ")))
      << users.out;
  auto usage = cli.Run({"users", "create", "bob", "--role", "analyst", "--label", "x"});
  EXPECT_EQ(usage.exit_code, 2);
  EXPECT_THAT(usage.err, HasSubstr("need --token"));
  auto bad_role = cli.Run({"users", "create", "bob", "--role", "nurse"});
  EXPECT_EQ(bad_role.exit_code, 2);
  auto nobody = cli.Run({"users", "issue-token", "nobody"});
  EXPECT_EQ(nobody.exit_code, 1);
  EXPECT_THAT(nobody.err, HasSubstr("no user named nobody"));
  // An analyst may not issue tokens: the server's 403.
  auto as_analyst = cli.Run({"users", "list"}, second);
  EXPECT_EQ(as_analyst.exit_code, 1);
  EXPECT_THAT(as_analyst.err, HasSubstr("[HTTP 403]"));

  auto deactivated = cli.Run({"users", "deactivate", "ana", "--reason", "left the lab"});
  ASSERT_EQ(deactivated.exit_code, 0) << deactivated.err;
  EXPECT_EQ(Call(http, "GET", "/api/v1/me", second).status, 401);
  EXPECT_EQ(server.Terminate(), 0);
}

// On a terminal --follow draws a redrawn bar with ETA instead of lines
// (in process: RunFesbenchCli with out_is_terminal = true).
TEST(CliSessionTest, FollowDrawsAProgressBarOnATerminal) {
  ServerProcess server;
  auto http = server.Client();
  const std::string admin = server.admin_token();
  auto truth = Call(http, "GET", "/api/v1/bench/virtual-subject", admin);
  ASSERT_EQ(truth.status, 200);
  ASSERT_EQ(Call(http, "POST", "/api/v1/subjects", admin,
                 {{"code", "TTY-1"},
                  {"details",
                   {{"weight_kg", truth.body["anthropometrics"]["body_mass_kg"]},
                    {"shank_length_cm",
                     truth.body["anthropometrics"]["shank_length_m"].get<double>() * 100.0}}}})
                .status,
            201);
  ASSERT_EQ(Call(http, "POST", "/api/v1/subjects/1/sessions", admin,
                 {{"leg", "left"},
                  {"date", "2026-11-21"},
                  {"threshold_ma", truth.body["threshold_ma"]},
                  {"max_tolerated_ma", truth.body["max_tolerated_ma"]}})
                .status,
            201);
  Cli cli;  // an empty config folder: --server and FESBENCH_TOKEN only
  ::setenv("XDG_CONFIG_HOME", (cli.dir() / "xdg").c_str(), 1);
  ::setenv("FESBENCH_TOKEN", admin.c_str(), 1);
  const std::string url = Url(server);
  const char* argv[] = {
      "fesbench", "--server", url.c_str(), "run", "start", "1", "rapid_parameterisation",
      "--follow"};
  std::ostringstream out, err;
  const int code = cli::RunFesbenchCli(8, argv, out, err, true);
  ::unsetenv("FESBENCH_TOKEN");
  ::unsetenv("XDG_CONFIG_HOME");
  ASSERT_EQ(code, 0) << err.str();
  EXPECT_THAT(out.str(), HasSubstr("\r[##############################] 100%  ETA "));
  EXPECT_THAT(out.str(), Not(HasSubstr("\nprogress "))) << "no plain lines on a terminal";
  EXPECT_THAT(out.str(), HasSubstr("\nend done parameter_set 1\n"));
  EXPECT_FALSE(fs::exists(cli.config_file())) << "only login writes the config file";
  EXPECT_EQ(server.Terminate(), 0);
}

// In (accelerated) real time the watchdog aborts a run whose controller
// stops heart-beating; `run start` follows and heart-beats by default, so
// its run ends done; --detach is refused; Ctrl-C cancels cleanly (exit 130).
TEST(CliSessionTest, FollowHeartBeatsARealTimeRun) {
  ServerProcess server({"--time-scale", "4"});
  Cli cli;
  ASSERT_EQ(cli.Run({"login", Url(server), "--token", server.admin_token()}).exit_code, 0);
  ASSERT_EQ(cli.Run({"subjects", "create", "RT-1"}).exit_code, 0);
  ASSERT_EQ(cli.Run({"sessions", "create", "--subject", "RT-1", "--leg", "left", "--date",
                     "2026-11-21", "--threshold-ma", "15", "--max-tolerated-ma", "40"})
                .exit_code,
            0);

  // A detached start of a stimulating protocol is refused, saying why.
  auto detached = cli.Run({"run", "start", "1", "isometric_ramp_irc", "--detach"});
  EXPECT_EQ(detached.exit_code, 2) << detached.out << detached.err;
  ExpectOneErrorLine(detached);
  EXPECT_THAT(detached.err, HasSubstr("stimulates the subject"));
  EXPECT_THAT(detached.err, HasSubstr("watchdog"));
  EXPECT_EQ(detached.out, "");

  // The watchdog stays: a run nobody heart-beats (started over the API) is aborted.
  auto http = server.Client();
  auto unattended = Call(http, "POST", "/api/v1/sessions/1/runs", server.admin_token(),
                         {{"protocol", "isometric_ramp_irc"}});
  ASSERT_EQ(unattended.status, 201) << unattended.text;
  std::string state;
  for (int i = 0; i < 100 && (state.empty() || state == "running" || state == "queued"); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    state = json::parse(cli.Run({"run", "show", "1", "--json"}).out)["state"];
  }
  EXPECT_EQ(state, "aborted");
  EXPECT_THAT(cli.Run({"run", "show", "1"}).out, HasSubstr("watchdog"));

  // Ctrl-C while following: the run is cancelled and the CLI exits 130
  // once the server confirmed the end.
  const pid_t pid = cli.Start({"run", "start", "1", "isometric_ramp_irc"});
  for (int i = 0; i < 200 && cli.OutSoFar().find("state running") == std::string::npos; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  ASSERT_THAT(cli.OutSoFar(), HasSubstr("state running"));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ::kill(pid, SIGINT);
  auto interrupted = cli.Finish(pid);
  EXPECT_EQ(interrupted.exit_code, 130) << interrupted.out << interrupted.err;
  EXPECT_THAT(interrupted.out, HasSubstr("interrupted: cancelling run 2"));
  EXPECT_THAT(interrupted.out, HasSubstr("\nend aborted\n"));
  EXPECT_EQ(json::parse(cli.Run({"run", "show", "2", "--json"}).out)["state"], "aborted");

  // Followed by default (16 s of bench time, 4 s of wall time): done.
  auto followed = cli.Run({"run", "start", "1", "isometric_ramp_irc"});
  ASSERT_EQ(followed.exit_code, 0) << followed.out << followed.err;
  EXPECT_THAT(followed.out, HasSubstr("trial isometric_ramp_irc stored as trial"));
  EXPECT_THAT(followed.out, HasSubstr("\nend done\n"));
  EXPECT_TRUE(std::regex_search(followed.out, std::regex("progress [0-9]+% eta [1-9][0-9]*s")))
      << "a real-time run has a non-zero ETA:\n"
      << followed.out;
  EXPECT_EQ(server.Terminate(), 0);
}

// README, "First session with a new subject": a new leg from the tolerance test to a validated
// model, by default, as a clinician walks it on a fresh server: new subject without
// inertia inputs → corrected → session without values → tolerance test
// (stopped with `run stop` at a chosen amplitude) → the session shows the
// recorded values → rapid parameterisation (followed by default) →
// prediction_random_binary and prediction_step → predict the new set on
// those fresh trials (not its training trials) with error figures.
// `max_stop_impact_deg_s` empty: the server's default gate limit.
void WalkANewLeg(const std::string& max_stop_impact_deg_s, bool expect_gate_refusal) {
  std::vector<std::string> flags = {"--time-scale", "10"};
  if (!max_stop_impact_deg_s.empty()) {
    flags.insert(flags.end(), {"--max-stop-impact-deg-s", max_stop_impact_deg_s});
  }
  ServerProcess server(flags);
  auto http = server.Client();
  const std::string admin = server.admin_token();
  const std::string clinician = CreateUserToken(http, admin, "clara", "clinician");
  auto truth = Call(http, "GET", "/api/v1/bench/virtual-subject", admin);
  ASSERT_EQ(truth.status, 200) << truth.text;
  const double mass_kg = truth.body["anthropometrics"]["body_mass_kg"];
  const double shank_cm = truth.body["anthropometrics"]["shank_length_m"].get<double>() * 100.0;
  const double true_max = truth.body["max_tolerated_ma"];
  Cli cli;
  ASSERT_EQ(cli.Run({"login", Url(server), "--token", clinician}).exit_code, 0);
  const auto step_ok = [](const CliRun& r) {
    return ::testing::AssertionResult(r.exit_code == 0) << "exit " << r.exit_code << "\n"
                                                        << r.out << r.err;
  };

  // 1. A new subject without weight or shank length, then corrected.
  ASSERT_TRUE(step_ok(cli.Run({"subjects", "create", "NEW-01", "--leg", "right"})));
  auto edited =
      cli.Run({"subjects", "edit", "NEW-01", "--reason", "measured at the bench", "--weight-kg",
               std::to_string(mass_kg), "--shank-length-cm", std::to_string(shank_cm)});
  ASSERT_TRUE(step_ok(edited));
  EXPECT_THAT(edited.out, HasSubstr("corrected: revision 2"));
  auto subject_shown = cli.Run({"subjects", "show", "NEW-01"});
  EXPECT_THAT(subject_shown.out, HasSubstr("measured at the bench"));
  EXPECT_THAT(subject_shown.out, HasSubstr("clara"));

  // 2. A session without threshold or max tolerated: rapid is refused.
  auto session = cli.Run(
      {"sessions", "create", "--subject", "NEW-01", "--leg", "right", "--date", "2026-11-23"});
  ASSERT_TRUE(step_ok(session));
  const std::int64_t session_id = LastNumber(session.out, "created session");
  ASSERT_GT(session_id, 0);
  const std::string sid = std::to_string(session_id);
  auto early = cli.Run({"run", "start", sid, "rapid_parameterisation"});
  EXPECT_EQ(early.exit_code, 1);
  EXPECT_THAT(early.err, HasSubstr("tolerance_test"));

  // 3. The tolerance test, followed by the CLI, stopped with `run stop` when
  // the ramp reaches the chosen amplitude (the clinician's "stop here").
  const double rate = 2.0, settle = 1.5, chosen_ma = std::floor(true_max) - 2.0;
  // `run stop` comes from a second terminal (Enter in the following one does the same).
  Cli second_terminal;
  ASSERT_EQ(second_terminal.Run({"login", Url(server), "--token", clinician}).exit_code, 0);
  const pid_t pid = cli.Start(
      {"run", "start", sid, "tolerance_test", "--param", "rate_ma_per_s=" + std::to_string(rate)});
  std::int64_t run_id = -1;
  for (int i = 0; i < 400 && run_id < 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    run_id = LastNumber(cli.OutSoFar(), "started run");
  }
  ASSERT_GT(run_id, 0) << cli.OutSoFar();
  const std::string run_path = "/api/v1/runs/" + std::to_string(run_id);
  for (int i = 0; i < 2000; ++i) {
    auto view = Call(http, "GET", run_path, clinician);
    if (view.body.value("bench_elapsed_s", 0.0) >= settle + chosen_ma / rate) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  auto stop = second_terminal.Run({"run", "stop", std::to_string(run_id)});
  ASSERT_TRUE(step_ok(stop));
  EXPECT_THAT(stop.out, HasSubstr("stop requested"));
  auto tolerance = cli.Finish(pid);
  ASSERT_TRUE(step_ok(tolerance));
  std::smatch recorded;
  ASSERT_TRUE(std::regex_search(
      tolerance.out, recorded,
      std::regex(
          R"(end done threshold_ma ([0-9.]+) max_tolerated_ma ([0-9.]+) session_revision 2)")))
      << tolerance.out;
  const double max_tolerated = std::stod(recorded[2]);
  // Starting `run stop` takes tens of ms of wall time, more on a loaded
  // machine: at time scale 10 and 2 mA/s each 50 ms is 1 mA more of the
  // ramp. Not below the chosen amplitude; a few mA above at most.
  EXPECT_GE(max_tolerated, chosen_ma - 1.0) << "stopped before the chosen amplitude";
  EXPECT_LE(max_tolerated, chosen_ma + 4.0) << "the stop came too late";
  std::cout << "[ stop     ] chosen " << chosen_ma << " mA, recorded " << max_tolerated << " mA\n";

  // 4. The session shows the recorded values at once.
  auto shown = cli.Run({"sessions", "show", sid});
  ASSERT_TRUE(step_ok(shown));
  EXPECT_THAT(shown.out, HasSubstr("revision 2\n"));
  EXPECT_THAT(shown.out, HasSubstr("threshold_ma: " + std::string(recorded[1])));
  EXPECT_THAT(shown.out, HasSubstr("max_tolerated_ma: " + std::string(recorded[2])));
  EXPECT_THAT(shown.out, HasSubstr("tolerance_test run " + std::to_string(run_id)));

  // 5. Rapid parameterisation, followed by default (no --follow).
  auto rapid = cli.Run({"run", "start", sid, "rapid_parameterisation"});
  ASSERT_TRUE(step_ok(rapid));
  EXPECT_THAT(rapid.out, HasSubstr("progress 100% "));
  const std::int64_t set_id = LastNumber(rapid.out, "end done parameter_set");
  ASSERT_GT(set_id, 0) << rapid.out;

  // 6. The prediction protocols on the new set: the model gate decides. A
  // refusal must be the gate speaking a clinician's language (which burst,
  // which stop, how fast) — never the old "leaves the range of motion".
  std::vector<std::string> fresh_kinds, gate_messages;
  for (const std::string protocol : {"prediction_random_binary", "prediction_step"}) {
    auto run = cli.Run({"run", "start", sid, protocol});
    if (run.exit_code == 0) {
      EXPECT_THAT(run.out, HasSubstr("\nend done\n")) << run.out;
      fresh_kinds.push_back(protocol);
      continue;
    }
    EXPECT_EQ(run.exit_code, 1) << run.out << run.err;
    ExpectOneErrorLine(run);
    EXPECT_THAT(run.err, AnyOf(HasSubstr("model-gated stimulation (parameter set " +
                                         std::to_string(set_id) + "): the stimulation from "),
                               HasSubstr("parameter set " + std::to_string(set_id) +
                                         " cannot simulate this input: ")));
    EXPECT_THAT(run.err, Not(HasSubstr("leaves the range of motion")));
    gate_messages.push_back(run.err);
    std::cout << "[ gate     ] " << run.err;
  }
  EXPECT_EQ(!gate_messages.empty(), expect_gate_refusal);
  if (fresh_kinds.empty()) {
    // Fresh free-swing trials all the same: active random binary is not gated.
    auto rb = cli.Run({"run", "start", sid, "active_random_binary"});
    ASSERT_TRUE(step_ok(rb));
    fresh_kinds = {"active_random_binary_rb1", "active_random_binary_rb2"};
  }

  // 7. Predict the new set on those fresh trials: validation by default.
  // (predictions are the analyst's)
  const std::string analyst = CreateUserToken(http, admin, "anton", "analyst");
  auto predict = cli.Run({"predict", "--params", std::to_string(set_id)}, analyst);
  ASSERT_TRUE(step_ok(predict));
  EXPECT_THAT(predict.out, HasSubstr("it was not fitted on (validation)"));
  EXPECT_THAT(predict.out, Not(HasSubstr("rapid_active_random_binary")))
      << "training trials are not the default";
  int rows = 0;
  for (const std::string& kind : fresh_kinds) {
    std::smatch m;
    ASSERT_TRUE(
        std::regex_search(predict.out, m, std::regex(kind + R"(  +([0-9.]+)  +([0-9.]+)  +deg)")))
        << kind << " in:\n"
        << predict.out;
    ++rows;
    EXPECT_GT(std::stod(m[1]), 0.0);
    EXPECT_LE(std::stod(m[2]), std::stod(m[1]) + 1e-3) << "E_ABS ≤ E_RMS";
    std::cout << "[ validate ] " << kind << " E_RMS " << m[1] << " deg, E_ABS " << m[2] << " deg\n";
  }
  EXPECT_EQ(rows, static_cast<int>(fresh_kinds.size()));
  // A training trial named explicitly is marked as such.
  const std::int64_t training_trial =
      LastNumber(rapid.out, "rapid_active_random_binary stored as trial");
  auto on_training = cli.Run(
      {"predict", "--params", std::to_string(set_id), "--stimulus", std::to_string(training_trial)},
      analyst);
  ASSERT_TRUE(step_ok(on_training));
  EXPECT_THAT(on_training.out, HasSubstr("is a training trial"));
  EXPECT_EQ(server.Terminate(), 0);
}

// Every setting at its default: the prediction protocols run after the
// default rapid run, and the new set is validated on their fresh trials.
TEST(CliSessionTest, NewLegFromToleranceTestToAValidatedModel) { WalkANewLeg("", false); }

// A stricter gate (90 deg/s) refuses the prediction protocols on this leg:
// they take the knee to full extension faster (§5.4.3's amplitude is the
// lowest giving full extension), and the refusal names burst, stop and
// speed. Fresh trials then come from active_random_binary.
TEST(CliSessionTest, NewLegWithAStricterModelGate) { WalkANewLeg("90", true); }

// The tolerance test ceiling (docs/SAFETY.md) from the command line: a tolerance test above the
// session's recorded max is refused without a reason, and started with
// --ceiling-reason, which is audited with the run.
TEST(CliSessionTest, AToleranceTestAboveTheRecordedMaxNeedsACeilingReason) {
  ServerProcess server({"--time-scale", "0"});
  auto http = server.Client();
  const std::string admin = server.admin_token();
  const std::string clinician = CreateUserToken(http, admin, "clara", "clinician");
  Cli cli;
  ASSERT_EQ(cli.Run({"login", Url(server), "--token", clinician}).exit_code, 0);
  ASSERT_EQ(cli.Run({"subjects", "create", "RE-01", "--leg", "right"}).exit_code, 0);
  auto session = cli.Run({"sessions", "create", "--subject", "RE-01", "--leg", "right", "--date",
                          "2026-11-24", "--threshold-ma", "5", "--max-tolerated-ma", "12"});
  ASSERT_EQ(session.exit_code, 0) << session.err;
  const std::string sid = std::to_string(LastNumber(session.out, "created session"));
  const std::vector<std::string> above = {"run",     "start",        sid, "tolerance_test",
                                          "--param", "ceiling_ma=14"};

  auto refused = cli.Run(above);
  EXPECT_EQ(refused.exit_code, 1);
  ExpectOneErrorLine(refused);
  EXPECT_THAT(refused.err, HasSubstr("needs an explicit ceiling_reason"));

  std::vector<std::string> with_reason = above;
  with_reason.insert(with_reason.end(), {"--ceiling-reason", "re-test after four weeks"});
  auto started = cli.Run(with_reason);
  ASSERT_EQ(started.exit_code, 0) << started.out << started.err;
  const std::int64_t run_id = LastNumber(started.out, "started run");
  auto audit = Call(http, "GET", "/api/v1/audit?limit=50", admin);
  ASSERT_EQ(audit.status, 200);
  bool audited = false;
  for (const auto& e : audit.body["items"]) {
    audited = audited || (e["action"] == "run.ceiling_above_max" &&
                          e["target"] == "runs/" + std::to_string(run_id) &&
                          e["request_summary"].get<std::string>().find(
                              "reason: re-test after four weeks") != std::string::npos);
  }
  EXPECT_TRUE(audited) << audit.text;
  EXPECT_EQ(server.Terminate(), 0);
}

// An older config file with wider permissions is narrowed to 0600.
TEST(CliConfigTest, SaveNarrowsAnExistingFileTo0600) {
  Cli cli;
  const fs::path path = cli.dir() / "cfg" / "config.json";
  fs::create_directories(path.parent_path());
  { std::ofstream(path) << "{}"; }
  ::chmod(path.c_str(), 0644);
  ASSERT_TRUE(cli::SaveConfig(path, {"http://h:1", "fsb_x"}).ok());
  struct stat st {};
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  auto loaded = cli::LoadConfig(path);
  ASSERT_TRUE(loaded.ok());
  EXPECT_EQ(loaded->server, "http://h:1");
  EXPECT_EQ(loaded->token, "fsb_x");
  { std::ofstream(path) << "[1]"; }
  EXPECT_FALSE(cli::LoadConfig(path).ok()) << "not an object";
}

}  // namespace
}  // namespace fesbench::testing
