#pragma once

/// @file
/// Registration functions of the `fesbench` commands, one per source file
/// (see cli.h), and helpers they share. RunFesbenchCli calls them in the
/// order listed in kCommands (cli.cc).

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <string_view>

#include "api/job.h"
#include "clients/cli/api_client.h"
#include "clients/cli/cli.h"

namespace fesbench::cli {

/// `login URL --token T|- | --token-file PATH` (login_command.cc).
void RegisterLoginCommand(CLI::App& app, CliContext& context);
/// `subjects list|show|create`, `sessions list|show|create` (records_commands.cc).
void RegisterRecordCommands(CLI::App& app, CliContext& context);
/// `protocols list|show` (protocol_commands.cc).
void RegisterProtocolCommands(CLI::App& app, CliContext& context);
/// `run start|show|stop|cancel`, `estop` (run_commands.cc).
void RegisterRunCommands(CLI::App& app, CliContext& context);
/// `params list|get`, `trials list|get` (data_commands.cc).
void RegisterDataCommands(CLI::App& app, CliContext& context);
/// `trials import`, `sessions export`, `params curves` (exchange_commands.cc;
/// registered after the groups they join).
void RegisterExchangeCommands(CLI::App& app, CliContext& context);
/// A subject's parameter history as wide CSV: one row per set (`items`, the
/// GET /parameter-sets summaries), one column per scalar parameter or
/// provenance field; numbers in their shortest exact form.
std::string ParameterHistoryCsv(ApiClient& client, std::int64_t subject_id,
                                const nlohmann::json& items,
                                const std::map<std::int64_t, std::string>& sides);
/// `identify`, `predict`, `compare` (analysis_commands.cc).
void RegisterAnalysisCommands(CLI::App& app, CliContext& context);
/// `study` (study_command.cc, clients/cli/study/).
void RegisterStudyCommand(CLI::App& app, CliContext& context);
/// `users list|create|deactivate|tokens|issue-token|revoke-token` (users_commands.cc).
void RegisterUserCommands(CLI::App& app, CliContext& context);

/// A client for the configured server (ResolveConnection).
std::unique_ptr<ApiClient> Connect(const CliContext& context);

/// A subject id from an id or a subject code (looked up on the server).
std::int64_t ResolveSubject(ApiClient& client, const std::string& id_or_code);

/// What a typed reader (api::…FromJson) made of a server's reply, or
/// CliError (server class) saying the reply was not a readable `what`.
template <typename T>
T FromServer(api::Result<T> read, std::string_view what) {
  if (!read.ok()) {
    throw CliError::Server("server sent an unreadable " + std::string(what) + ": " +
                           read.status().ToString());
  }
  return *std::move(read);
}

/// Polls GET /jobs/{id} until the job is done or failed, waiting
/// `first_delay` between the first polls and doubling up to `max_delay`.
api::JobReport AwaitJob(ApiClient& client, std::int64_t job_id,
                        std::chrono::milliseconds first_delay = std::chrono::milliseconds(20),
                        std::chrono::milliseconds max_delay = std::chrono::milliseconds(250));

/// AwaitJob's result, or CliError with the failed job's error message.
nlohmann::json WaitForJob(ApiClient& client, std::int64_t job_id);

}  // namespace fesbench::cli
