// `fesbench login URL (--token T | --token - | --token-file PATH)`: checks
// the token with the server (GET /me), then stores the server and token in
// the per-user config file (mode 0600, config.h). `--token -` and
// `--token-file` keep the token out of the process list.

#include <memory>
#include <ostream>
#include <string>

#include "api/user.h"
#include "clients/cli/commands.h"
#include "clients/cli/config.h"
#include "clients/cli/output.h"

namespace fesbench::cli {

void RegisterLoginCommand(CLI::App& app, CliContext& context) {
  auto url = std::make_shared<std::string>();
  auto token = std::make_shared<std::string>();
  CLI::App* sub = app.add_subcommand(
      "login", "Store the server URL and bearer token in the per-user config file (mode 0600).");
  sub->add_option("url", *url, "server URL, e.g. http://127.0.0.1:8080")->required();
  sub->add_option("--token", *token,
                  "bearer token (fsb_...) issued by an admin; '-' reads it from standard input "
                  "(or give --token-file PATH)");
  sub->callback([url, token, &context] {
    context.action = [url, token, &context] {
      std::string secret = *token == "-" ? ReadToken("-") : *token;
      if (secret.empty()) secret = context.options.token;  // --token-file
      if (secret.empty()) {
        throw CliError::Usage(
            "login needs --token T, --token - (standard input) or "
            "--token-file PATH");
      }
      CliConfig config{NormaliseServerUrl(*url), secret};
      // The token must be valid: /me names its user for any signed-in role.
      ApiClient client(config);
      const nlohmann::json me = client.Get("/me");
      auto path = ConfigPath();
      if (!path.ok()) throw CliError::Usage(path.status().ToString());
      if (auto st = SaveConfig(*path, config); !st.ok()) throw CliError(kExitServer, st.ToString());
      if (context.options.json) {
        context.out << nlohmann::json{{"server", config.server},
                                      {"config_file", path->string()},
                                      {"user", me}}
                           .dump(2)
                    << "\n";
        return;
      }
      const api::User user = FromServer(api::UserFromJson(me), "user");
      context.out << "logged in to " << config.server << " as " << user.name << " ("
                  << api::RoleName(user.role) << "); configuration in " << path->string() << "\n";
    };
  });
}

}  // namespace fesbench::cli
