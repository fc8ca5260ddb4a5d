// `fesbench study`: the virtual-cohort study of thesis ch. 6 and §7.4.1
// against a running server with a simulated bench (clients/cli/study/).

#include <chrono>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "clients/cli/commands.h"
#include "clients/cli/study/study.h"

namespace fesbench::cli {

namespace {

struct StudyForm {
  int legs = 16;
  std::uint64_t seed = 1;
  std::string out = "study-out";
  std::string date = "2026-01-01";
  bool no_plots = false;
  std::vector<std::string> families = {"thesis", "analytic"};
};

}  // namespace

void RegisterStudyCommand(CLI::App& app, CliContext& context) {
  auto form = std::make_shared<StudyForm>();
  CLI::App* cmd = app.add_subcommand(
      "study",
      "Run the thesis's identification study on a seeded virtual cohort (admin; simulated "
      "bench): tables 6.1-6.9, per-leg errors, bench times and plots into --out.");
  cmd->add_option("--legs", form->legs, "number of virtual legs (default 16)")
      ->check(CLI::Range(2, 1000));
  cmd->add_option("--seed", form->seed, "cohort seed (default 1)");
  cmd->add_option("--families", form->families,
                  "shape families of the legs, taken in turn: thesis, analytic, plateau "
                  "(default thesis,analytic)")
      ->delimiter(',')
      ->check(CLI::IsMember({"thesis", "analytic", "plateau"}));
  cmd->add_option("--out", form->out, "output folder (default study-out)");
  cmd->add_option("--date", form->date, "session date YYYY-MM-DD");
  cmd->add_flag("--no-plots", form->no_plots, "do not run gnuplot");
  cmd->callback([form, &context] {
    context.action = [form, &context] {
      auto client = Connect(context);
      study::StudyOptions options;
      options.legs = form->legs;
      options.seed = form->seed;
      options.output_dir = form->out;
      options.date = form->date;
      options.plots = !form->no_plots;
      options.families = form->families;
      const auto start = std::chrono::steady_clock::now();
      const study::StudySummary summary = study::RunStudy(*client, options, context.err);
      const double wall_s =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (context.options.json) {
        context.out << nlohmann::json{{"legs_done", summary.legs_done},
                                      {"identifications_failed", summary.identifications_failed},
                                      {"wall_s", wall_s},
                                      {"out", form->out},
                                      {"plots_drawn", summary.plots_drawn},
                                      {"plot_note", summary.plot_note}}
                           .dump(2)
                    << "\n";
        return;
      }
      context.out << "study: " << summary.legs_done << " legs, " << summary.identifications_failed
                  << " identifications failed, wall " << wall_s << " s; tables in " << form->out
                  << "\n";
      if (!summary.plots_drawn) context.out << "study: " << summary.plot_note << "\n";
    };
  });
}

}  // namespace fesbench::cli
