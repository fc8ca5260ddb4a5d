#include "clients/cli/config.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <iostream>
#include <nlohmann/json.hpp>

#include "api/trial.h"

namespace fesbench::cli {

api::Result<std::filesystem::path> ConfigPath() {
  const char* xdg = std::getenv("XDG_CONFIG_HOME");
  if (xdg != nullptr && xdg[0] == '/') {
    return std::filesystem::path(xdg) / "fesbench" / "config.json";
  }
  const char* home = std::getenv("HOME");
  if (home != nullptr && home[0] != '\0') {
    return std::filesystem::path(home) / ".config" / "fesbench" / "config.json";
  }
  return api::Status::FailedPrecondition("neither XDG_CONFIG_HOME nor HOME is set");
}

api::Result<CliConfig> LoadConfig(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return CliConfig{};
  auto text = api::ReadTextFile(path);
  if (!text.ok()) return text.status();
  const nlohmann::json j = nlohmann::json::parse(*text, nullptr, false);
  if (j.is_discarded() || !j.is_object()) {
    return api::Status::InvalidArgument(path.string() + " is not a JSON object");
  }
  CliConfig config;
  for (const auto& [key, target] :
       {std::pair<const char*, std::string*>{"server", &config.server}, {"token", &config.token}}) {
    if (!j.contains(key)) continue;
    if (!j[key].is_string()) {
      return api::Status::InvalidArgument(path.string() + ": must be a string", key);
    }
    *target = j[key].get<std::string>();
  }
  return config;
}

api::Status SaveConfig(const std::filesystem::path& path, const CliConfig& config) {
  std::error_code ec;
  const auto dir = path.parent_path();
  if (!std::filesystem::exists(dir, ec)) {
    std::filesystem::create_directories(dir, ec);
    if (ec) return api::Status::Unavailable("cannot create " + dir.string() + ": " + ec.message());
    ::chmod(dir.c_str(), 0700);
  }
  const std::string text =
      nlohmann::json{{"server", config.server}, {"token", config.token}}.dump(2) + "\n";
  // Created 0600 from the start (the token never sits in a readable file),
  // and narrowed if an older file was wider.
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) return api::Status::Unavailable("cannot write " + path.string());
  bool ok = ::fchmod(fd, 0600) == 0;
  std::size_t written = 0;
  while (ok && written < text.size()) {
    const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
    if (n <= 0)
      ok = false;
    else
      written += static_cast<std::size_t>(n);
  }
  ok = (::close(fd) == 0) && ok;
  if (!ok) return api::Status::Unavailable("cannot write " + path.string());
  return api::Status();
}

std::string NormaliseServerUrl(const std::string& url) {
  std::string u = url;
  while (!u.empty() && u.back() == '/') u.pop_back();
  const bool http = u.rfind("http://", 0) == 0;
  const bool https = u.rfind("https://", 0) == 0;
  const std::size_t host_at = http ? 7 : 8;
  if ((!http && !https) || u.size() <= host_at) {
    throw CliError::Usage("server URL must be http://HOST[:PORT] or https://HOST[:PORT], got '" +
                          url + "'");
  }
  if (u.find('/', host_at) != std::string::npos) {
    throw CliError::Usage("server URL must not have a path (the API is under /api/v1): '" + url +
                          "'");
  }
  return u;
}

std::string ReadToken(const std::string& source) {
  std::string text;
  if (source == "-") {
    std::getline(std::cin, text);
  } else {
    auto read = api::ReadTextFile(source);
    if (!read.ok()) throw CliError::Usage("token file: " + read.status().ToString());
    text = *read;
  }
  const auto first = text.find_first_not_of(" \t\r\n");
  const auto last = text.find_last_not_of(" \t\r\n");
  if (first == std::string::npos) {
    throw CliError::Usage(source == "-" ? "no token on standard input"
                                        : "token file " + source + " is empty");
  }
  text = text.substr(first, last - first + 1);
  if (text.find_first_of(" \t\r\n") != std::string::npos) {
    throw CliError::Usage("the token must be one word (" +
                          (source == "-" ? std::string("standard input") : source) + ")");
  }
  return text;
}

CliConfig ResolveConnection(const GlobalOptions& options) {
  CliConfig config;
  if (auto path = ConfigPath(); path.ok()) {
    auto loaded = LoadConfig(*path);
    if (!loaded.ok()) throw CliError::Usage("config file: " + loaded.status().ToString());
    config = *loaded;
  }
  if (!options.server.empty()) config.server = options.server;
  if (const char* token = std::getenv("FESBENCH_TOKEN"); token != nullptr && token[0] != '\0') {
    config.token = token;
  }
  if (!options.token.empty()) config.token = options.token;
  if (config.server.empty()) {
    throw CliError::Usage("no server: run 'fesbench login URL --token T' or pass --server URL");
  }
  config.server = NormaliseServerUrl(config.server);
  return config;
}

}  // namespace fesbench::cli
