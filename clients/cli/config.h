#pragma once

/// @file
/// The per-user configuration of `fesbench`: the server URL and bearer
/// token stored by `fesbench login`, in
/// `$XDG_CONFIG_HOME/fesbench/config.json` (or `$HOME/.config/fesbench/...`)
/// as `{"server": "...", "token": "..."}`, created with mode 0600 in a 0700
/// folder. `--server`, `--token-file` and the FESBENCH_TOKEN environment
/// variable override it.

#include <filesystem>
#include <string>

#include "api/status.h"
#include "clients/cli/cli.h"

namespace fesbench::cli {

struct CliConfig {
  std::string server;  ///< base URL, e.g. "https://lab.example:8443".
  std::string token;   ///< bearer token ("fsb_…").
};

/// The config file's path from $XDG_CONFIG_HOME, else $HOME/.config;
/// kFailedPrecondition when neither is set.
api::Result<std::filesystem::path> ConfigPath();

/// Reads the config file; an absent file is an empty config. kInvalidArgument
/// when the file is not the JSON object above.
api::Result<CliConfig> LoadConfig(const std::filesystem::path& path);

/// Writes the config file with mode 0600 (also when it already existed with
/// wider permissions); its folder is created with mode 0700.
api::Status SaveConfig(const std::filesystem::path& path, const CliConfig& config);

/// A bearer token read from `source`: a file path, or "-" for the first
/// line of standard input; surrounding white space is dropped. Throws
/// CliError (usage) when it cannot be read or is empty.
std::string ReadToken(const std::string& source);

/// The server and token to use: --server over the file's server, and
/// --token-file over FESBENCH_TOKEN over the file's token. Throws CliError
/// (usage) when no server is known.
CliConfig ResolveConnection(const GlobalOptions& options);

/// Checks and normalises a server URL: http:// or https://, a host, no
/// trailing slash. Throws CliError (usage) otherwise.
std::string NormaliseServerUrl(const std::string& url);

}  // namespace fesbench::cli
