// `fesbench-model example`: writes the example parameter set (a plausible
// healthy knee, model::ExampleParameterSet) as JSON, so a new user has a
// valid --params file to start from.

#include <memory>
#include <ostream>
#include <string>

#include "api/parameter_set_json.h"
#include "api/trial.h"
#include "clients/model_cli/commands.h"
#include "model/parameter_set.h"

namespace fesbench::cli {

void RegisterExampleCommand(CLI::App& app, CliContext& context) {
  auto out_path = std::make_shared<std::string>("-");
  CLI::App* sub = app.add_subcommand(
      "example", "Write the example parameter set (docs/MODEL.md JSON) to start from.");
  sub->add_option("--out", *out_path, "output file ('-' for standard output, the default)");
  sub->callback([out_path, &context] {
    const std::string text =
        api::ParameterSetToJson(model::ExampleParameterSet()).dump(2) + "\n";
    if (*out_path == "-") {
      context.out << text;
      return;
    }
    const api::Status written = api::WriteTextFile(*out_path, text);
    if (!written.ok()) throw CliError::BadInput(written.ToString());
  });
}

}  // namespace fesbench::cli
