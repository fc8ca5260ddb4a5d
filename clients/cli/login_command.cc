// `fesbench login URL --token T`: checks the server answers, then stores the
// server and token in the per-user config file (mode 0600, config.h).

#include <memory>
#include <ostream>
#include <string>

#include "clients/cli/commands.h"
#include "clients/cli/config.h"

namespace fesbench::cli {

void RegisterLoginCommand(CLI::App& app, CliContext& context) {
  auto url = std::make_shared<std::string>();
  auto token = std::make_shared<std::string>();
  CLI::App* sub = app.add_subcommand(
      "login", "Store the server URL and bearer token in the per-user config file (mode 0600).");
  sub->add_option("url", *url, "server URL, e.g. http://127.0.0.1:8080")->required();
  sub->add_option("--token", *token, "bearer token (fsb_...) issued by an admin")->required();
  sub->callback([url, token, &context] {
    context.action = [url, token, &context] {
      CliConfig config{NormaliseServerUrl(*url), *token};
      // The token must be valid: /subjects needs any signed-in role.
      ApiClient client(config);
      client.Get("/subjects?limit=1");
      auto path = ConfigPath();
      if (!path.ok()) throw CliError::Usage(path.status().ToString());
      if (auto st = SaveConfig(*path, config); !st.ok()) throw CliError(kExitServer, st.ToString());
      context.out << "logged in to " << config.server << "; configuration in " << path->string()
                  << "\n";
    };
  });
}

}  // namespace fesbench::cli
