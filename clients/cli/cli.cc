#include "clients/cli/cli.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <ostream>
#include <string>
#include <thread>
#include <utility>

#include "api/subject.h"
#include "clients/cli/commands.h"
#include "clients/cli/config.h"
#include "clients/command_line.h"

namespace fesbench::cli {
namespace {

// Every command, in the order `--help` lists them.
constexpr CommandRegistrar kCommands[] = {
    RegisterLoginCommand, RegisterRecordCommands,   RegisterProtocolCommands, RegisterRunCommands,
    RegisterDataCommands, RegisterExchangeCommands, RegisterAnalysisCommands,
    RegisterStudyCommand,   RegisterUserCommands,
};

int Fail(std::ostream& err, int code, const std::string& message) {
  err << "fesbench: error: " << OneLine(message) << std::endl;
  return code;
}

}  // namespace

std::unique_ptr<ApiClient> Connect(const CliContext& context) {
  return std::make_unique<ApiClient>(ResolveConnection(context.options));
}

std::int64_t ResolveSubject(ApiClient& client, const std::string& id_or_code) {
  if (!id_or_code.empty() && id_or_code.find_first_not_of("0123456789") == std::string::npos) {
    return std::stoll(id_or_code);
  }
  const std::vector<api::Subject> found = client.GetItemsOf(
      "/subjects?code=" + UrlEncode(id_or_code), &api::SubjectFromJson, "subject");
  if (found.empty()) throw CliError::Server("server: no subject with code '" + id_or_code + "'");
  return found.front().id;
}

api::JobReport AwaitJob(ApiClient& client, std::int64_t job_id,
                        std::chrono::milliseconds first_delay, std::chrono::milliseconds max_delay) {
  auto delay = first_delay;
  for (;;) {
    api::JobReport job =
        FromServer(api::JobReportFromJson(client.Get("/jobs/" + std::to_string(job_id))), "job");
    if (job.state == api::JobState::kDone || job.state == api::JobState::kFailed) return job;
    std::this_thread::sleep_for(delay);
    delay = std::min(delay * 2, max_delay);
  }
}

nlohmann::json WaitForJob(ApiClient& client, std::int64_t job_id) {
  api::JobReport job = AwaitJob(client, job_id);
  if (job.state == api::JobState::kDone) return std::move(job.result);
  std::string message = job.error.message();
  if (!job.error.field().empty()) message += " (field " + job.error.field() + ")";
  throw CliError::Server("server: job " + std::to_string(job_id) + " failed: " + message);
}

int RunFesbenchCli(int argc, const char* const* argv, std::ostream& out, std::ostream& err,
                   bool out_is_terminal) {
  try {
    CliContext context{out, err, out_is_terminal, {}, {}};
    CLI::App app(
        "fesbench: the analyst command line of a fesbench server (subjects, sessions, runs,\n"
        "parameter sets, trials, identification, prediction, comparison).\n"
        "Exit codes: 0 ok, 1 error reported by the server, 2 usage error, 3 server unreachable.",
        "fesbench");
    app.require_subcommand(1);
    app.fallthrough(true);  // global options may follow the subcommand
    app.add_option("--server", context.options.server,
                   "server URL, e.g. https://lab:8443 (overrides the config file)");
    app.add_option("--token-file", context.options.token_file,
                   "read the bearer token from this file ('-': standard input) instead of the "
                   "config file or FESBENCH_TOKEN (keeps it out of the process list)");
    app.add_flag("--json", context.options.json,
                 "machine-readable output: one JSON document, or one JSON object per line while "
                 "`run start` follows a run");
    app.set_version_flag("--version", std::string("fesbench ") + FESBENCH_VERSION);
    for (CommandRegistrar registrar : kCommands) registrar(app, context);
    const ParseOutcome parsed = ParseCommandLine(app, argc, argv, out);
    if (parsed.help_printed) return kExitOk;
    if (!parsed.usage_error.empty()) return Fail(err, kExitUsage, parsed.usage_error);
    if (!context.action) return Fail(err, kExitUsage, "no command given (see --help)");
    if (!context.options.token_file.empty()) {
      context.options.token = ReadToken(context.options.token_file);
    }
    context.action();
    out.flush();
    return kExitOk;
  } catch (const CliError& e) {
    return Fail(err, e.exit_code(), e.what());
  } catch (const std::exception& e) {
    return Fail(err, kExitServer, e.what());
  } catch (...) {
    return Fail(err, kExitServer, "unexpected failure");
  }
}

}  // namespace fesbench::cli
