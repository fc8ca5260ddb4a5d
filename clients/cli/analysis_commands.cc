// `fesbench identify`, `predict` and `compare`: the analysis jobs of the
// server (docs/MODEL.md; docs/API.md, "Jobs"; thesis ch. 4, §5.4.5, §7.4). Each submits a job,
// waits for it, and prints its result.

#include <algorithm>
#include <cstdio>
#include <map>
#include <memory>
#include <ostream>
#include <optional>
#include <string>
#include <vector>

#include "api/analysis_requests.h"
#include "api/trial.h"
#include "clients/cli/commands.h"
#include "clients/cli/output.h"

namespace fesbench::cli {

namespace {

using nlohmann::json;

// The short stimulus names of `predict` and the generators they denote
// (model/stimulus_generators.h; the §5.4.5 prediction stimuli and §5.4.4 RB).
const std::map<std::string, std::string>& StimulusAliases() {
  static const std::map<std::string, std::string> aliases = {
      {"step", "prediction_step"},
      {"ramp", "prediction_ramp"},
      {"sine", "prediction_sine"},
      {"rb", "random_binary_dense"},
  };
  return aliases;
}

std::string Fixed(const json& value, int digits) {
  if (!value.is_number()) return "-";
  char buffer[48];
  std::snprintf(buffer, sizeof buffer, "%.*f", digits, value.get<double>());
  return buffer;
}

// A trial recorded in free swing (the knee angle is what is predicted), by
// the kind the server stored with it (api::IsFreeSwing).
bool IsFreeSwingTrial(const json& trial) {
  const json kind = trial.value("kind", json(nullptr));
  if (!kind.is_string()) return false;
  const std::optional<api::TrialKind> parsed = api::ParseTrialKind(kind.get<std::string>());
  return parsed && api::IsFreeSwing(*parsed);
}

// The trials a parameter set was fitted on (its provenance): training data.
std::vector<std::int64_t> TrainingTrials(const json& set) {
  std::vector<std::int64_t> ids;
  for (const auto& id : set.value("trial_ids", json::array())) {
    if (id.is_number_integer()) ids.push_back(id.get<std::int64_t>());
  }
  return ids;
}

bool Contains(const std::vector<std::int64_t>& ids, std::int64_t id) {
  return std::find(ids.begin(), ids.end(), id) != ids.end();
}

// Honest validation by default: the free-swing trials of the
// set's leg (every session of its subject) that the set was NOT fitted on.
json ValidationTrials(ApiClient& client, std::int64_t set_id) {
  const json set = client.Get("/parameter-sets/" + std::to_string(set_id));
  const std::vector<std::int64_t> training = TrainingTrials(set);
  const std::int64_t subject = set.value("subject_id", std::int64_t{0});
  const std::int64_t leg = set.value("leg_id", std::int64_t{0});
  json kept = json::array();
  for (const auto& session :
       client.GetAllPages("/subjects/" + std::to_string(subject) + "/sessions", "")) {
    if (session.value("leg_id", std::int64_t{-1}) != leg) continue;
    for (const auto& trial :
         client.GetAllPages("/sessions/" + Cell(session["id"]) + "/trials", "")) {
      const std::int64_t id = trial.value("id", std::int64_t{0});
      if (IsFreeSwingTrial(trial) && !Contains(training, id)) {
        kept.push_back(id);
      }
    }
  }
  if (kept.empty()) {
    throw CliError::Usage(
        "parameter set " + std::to_string(set_id) +
        " has no free-swing trial of its leg that it was not fitted on (it was fitted on trials " +
        set.value("trial_ids", json::array()).dump() +
        "): record one (e.g. `fesbench run start SESSION prediction_random_binary`) or name "
        "trials with --trials (training trials are then marked as such)");
  }
  return kept;
}

// A pair's trial ids, comma-separated.
std::string TrialList(const json& trials) {
  std::string text;
  for (const auto& t : trials) text += (text.empty() ? "" : ",") + Cell(t["trial_id"]);
  return text;
}

// Says on standard error which of `trials` a set of `sets` was fitted on.
void NoteTrainingTrials(ApiClient& client, CliContext& context,
                        const std::vector<std::int64_t>& sets,
                        const std::vector<std::int64_t>& trials) {
  for (std::int64_t set : sets) {
    const std::vector<std::int64_t> training =
        TrainingTrials(client.Get("/parameter-sets/" + std::to_string(set)));
    for (std::int64_t t : trials) {
      if (Contains(training, t)) {
        context.err << "note: trial " << t << " is a training trial of parameter set " << set
                    << " (it was fitted on it)\n";
      }
    }
  }
}

struct IdentifyForm {
  std::string session;
  std::string method = "thesis";
  std::string passive_method;
  std::string irc_method;
  std::optional<double> inertia_kgm2;
  std::optional<double> gravity_moment_nm;
};

struct PredictForm {
  std::string params;
  std::string stimulus;
  std::vector<std::string> stimulus_params;
  std::string mode;
  std::string out_path;
  bool fit_scale = false;
};

struct CompareForm {
  std::vector<std::string> a;
  std::vector<std::string> b;
  std::vector<std::string> trials;
  std::string metric;
  double confidence = 0.0;
};

}  // namespace

void RegisterAnalysisCommands(CLI::App& app, CliContext& context) {
  {
    auto form = std::make_shared<IdentifyForm>();
    CLI::App* identify = app.add_subcommand(
        "identify", "Fit a parameter set from a session's stored trials (analyst or admin).");
    identify->add_option("--session", form->session, "session id")->required();
    identify
        ->add_option("--method", form->method,
                     "thesis (chapter 4), rapid (§7.4.1) or passive (the passive curves alone "
                     "from unstimulated swings, e.g. a pendulum test)")
        ->check(CLI::IsMember(api::IdentificationMethodNames()));
    identify
        ->add_option("--inertia-kgm2", form->inertia_kgm2,
                     "the limb inertia J, kg·m² (default: from the subject's weight and shank "
                     "length, Eq. 4.13; method rapid: else the leg's approved set; method "
                     "passive: identified from the swings)")
        ->check(CLI::Range(0.01, 10.0));
    identify
        ->add_option("--gravity-moment-nm", form->gravity_moment_nm,
                     "method passive: m·g·l of shank and foot, N·m, from which J is identified "
                     "(default: from the subject's weight and shank length)")
        ->check(CLI::Range(0.1, 100.0));
    identify
        ->add_option("--passive-method", form->passive_method,
                     "sequential (§4.2.1), simultaneous (Eq. 4.31) or free_swing (Eq. 4.35); "
                     "method rapid fits in free swing and refuses the others")
        ->check(CLI::IsMember(api::PassiveMethodNames()));
    identify->add_option("--irc-method", form->irc_method,
                         "IRC method, e.g. ramp_correlation (method rapid: only that one)");
    identify->callback([form, &context] {
      context.action = [form, &context] {
        api::IdentificationRequest request;
        request.session_id = ParseId(form->session, "session");
        request.method = model::IdentificationMethodFromName(form->method).value_or(request.method);
        request.inertia_kgm2 = form->inertia_kgm2;
        request.gravity_moment_nm = form->gravity_moment_nm;
        // Every flag given reaches the request as given, even where the
        // method has its own (rapid): the server then refuses it by name.
        json body = api::IdentificationRequestToJson(request);
        if (!form->passive_method.empty()) body["passive_method"] = form->passive_method;
        if (!form->irc_method.empty()) body["irc_method"] = form->irc_method;
        auto client = Connect(context);
        const json job = client->Post("/identifications", body);
        const json result = WaitForJob(*client, job["id"].get<std::int64_t>());
        if (context.options.json) {
          context.out << result.dump(2) << "\n";
          return;
        }
        const json sets =
            result.contains("parameter_sets") ? result["parameter_sets"] : json::array();
        for (const auto& set : sets) {
          context.out << "parameter set " << Cell(set["id"]) << " (version " << Cell(set["version"])
                      << ", model " << Cell(set["model"]) << ")\n";
        }
        context.out << "report:\n";
        if (result.contains("report")) PrintObject(context.out, result["report"], 2);
      };
    });
  }
  {
    auto form = std::make_shared<PredictForm>();
    CLI::App* predict = app.add_subcommand(
        "predict",
        "Simulate a parameter set on a stimulus or a stored trial; E_RMS/E_ABS against the "
        "trial's measured angle.");
    predict->add_option("--params", form->params, "parameter set id")->required();
    predict->add_option("--stimulus", form->stimulus,
                        "step, ramp, sine, rb (random binary), another generator name, or a "
                        "TRIAL_ID to predict a recorded trial (default: every free-swing trial of "
                        "the set's leg it was not fitted on)");
    predict->add_option("--param", form->stimulus_params,
                        "stimulus generator parameter key=value (repeatable)");
    predict->add_option("--mode", form->mode, "free_swing or isometric")
        ->check(CLI::IsMember({"free_swing", "isometric"}));
    predict->add_option("--out", form->out_path, "write the predicted trajectory as CSV");
    predict->add_flag("--fit-scale", form->fit_scale,
                      "isometric trial: scale the predicted torque by the best-fit constant "
                      "(§6.1.2) before the errors");
    predict->callback([form, &context] {
      context.action = [form, &context] {
        const std::int64_t set_id = ParseId(form->params, "--params");
        if (form->stimulus.empty()) {
          // Held-out validation: each trial the set was not fitted on.
          if (!form->out_path.empty() || !form->stimulus_params.empty()) {
            throw CliError::Usage("--out and --param need one --stimulus");
          }
          auto client = Connect(context);
          const json trials = ValidationTrials(*client, set_id);
          json results = json::array();
          std::vector<std::vector<std::string>> rows;
          for (const auto& trial : trials) {
            api::PredictionRequest request;
            request.parameter_set_id = set_id;
            request.trial_id = trial.get<std::int64_t>();
            request.mode = api::ParsePredictionMode(form->mode);
            const json job = client->Post("/predictions", api::PredictionRequestToJson(request));
            json result = WaitForJob(*client, job["id"].get<std::int64_t>());
            result.erase("columns");
            const json errors = result.value("errors", json(nullptr));
            const json name = client->Get("/trials/" + Cell(trial)).value("name", json(nullptr));
            rows.push_back({Cell(trial), Cell(name),
                            errors.is_object() ? Fixed(errors["e_rms"], 3) : "-",
                            errors.is_object() ? Fixed(errors["e_abs"], 3) : "-",
                            errors.is_object() ? Cell(errors.value("unit", json(nullptr))) : "-",
                            Cell(result.value("prediction_id", json(nullptr)))});
            results.push_back(std::move(result));
          }
          if (context.options.json) {
            context.out << results.dump(2) << "\n";
            return;
          }
          context.out << "parameter set " << set_id
                      << " on the free-swing trials it was not fitted on (validation):\n";
          PrintTable(context.out, {"trial", "name", "E_RMS", "E_ABS", "unit", "prediction"}, rows);
          return;
        }
        api::PredictionRequest request;
        request.parameter_set_id = set_id;
        const bool is_trial = form->stimulus.find_first_not_of("0123456789") == std::string::npos;
        if (is_trial) {
          request.trial_id = ParseId(form->stimulus, "--stimulus trial");
          if (!form->stimulus_params.empty()) {
            throw CliError::Usage("--param applies to a stimulus generator, not to a trial");
          }
        } else {
          const auto alias = StimulusAliases().find(form->stimulus);
          const std::string generator =
              alias == StimulusAliases().end() ? form->stimulus : alias->second;
          api::StimulusSpec stimulus{generator};
          for (const auto& text : form->stimulus_params) {
            const auto [key, value] = ParseKeyValue(text);
            stimulus.params[key] = value;
          }
          request.stimulus = std::move(stimulus);
        }
        request.mode = api::ParsePredictionMode(form->mode);
        request.fit_scale = form->fit_scale;
        auto client = Connect(context);
        const json job = client->Post("/predictions", api::PredictionRequestToJson(request));
        json result = WaitForJob(*client, job["id"].get<std::int64_t>());
        const bool training =
            request.trial_id.has_value() &&
            Contains(TrainingTrials(client->Get("/parameter-sets/" + std::to_string(set_id))),
                     *request.trial_id);
        if (!form->out_path.empty()) {
          api::ChannelGroup group;
          group.sample_rate_hz = result.value("sample_rate_hz", 200.0);
          if (!result.contains("columns") || !result["columns"].is_object()) {
            throw CliError::Server("server: the prediction has no columns");
          }
          for (const auto& [name, values] : result["columns"].items()) {
            group.Set(name, values.get<std::vector<double>>());
          }
          if (const api::Status st = api::ValidateChannelGroup(group); !st.ok()) {
            throw CliError::Server("server sent an invalid prediction: " + st.ToString());
          }
          // t_s first, as every fesbench CSV.
          std::stable_partition(group.channels.begin(), group.channels.end(),
                                [](const api::Channel& c) { return c.name == api::kTimeChannel; });
          WriteOutput(context, form->out_path, api::GroupToCsv(group));
        }
        if (context.options.json) {
          result.erase("columns");
          context.out << result.dump(2) << "\n";
          return;
        }
        context.out << "prediction " << Cell(result.value("prediction_id", json(nullptr)))
                    << ": parameter set " << Cell(result["parameter_set_id"]) << ", "
                    << Cell(result.value("mode", json(nullptr))) << ", "
                    << Cell(result.value("samples", json(nullptr))) << " samples\n";
        const json errors = result.value("errors", json(nullptr));
        if (errors.is_object()) {
          const std::string unit = errors.value("unit", "");
          context.out << "E_RMS " << Fixed(errors["e_rms"], 3) << " " << unit << "  E_ABS "
                      << Fixed(errors["e_abs"], 3) << " " << unit << "  (trial "
                      << Cell(result["trial_id"]) << ", " << Cell(errors["channel"]) << ", "
                      << Cell(errors["samples"]) << " samples)\n";
          if (training) {
            context.out << "note: trial " << Cell(result["trial_id"]) << " is a training trial: "
                        << "parameter set " << set_id
                        << " was fitted on it, so these errors are not a validation\n";
          }
          if (result.contains("fitted_scale") && result["fitted_scale"].is_number()) {
            context.out << "fitted scale " << Fixed(result["fitted_scale"], 4)
                        << " (§6.1.2)  normalised E_RMS "
                        << Fixed(errors.value("normalised_rms", json(nullptr)), 4) << "  E_AVE "
                        << Fixed(errors.value("e_ave", json(nullptr)), 5) << "\n";
          }
        } else {
          context.out << "no measured trial: no errors computed\n";
        }
      };
    });
  }
  {
    auto form = std::make_shared<CompareForm>();
    CLI::App* compare = app.add_subcommand(
        "compare",
        "Paired t-test of two groups of parameter sets' prediction errors (pair i = the i-th "
        "set of each group, one subject/leg); one set on each side: one pair per trial.");
    compare->add_option("--params-a", form->a, "parameter set ids of group A (comma-separated)")
        ->required()
        ->delimiter(',');
    compare->add_option("--params-b", form->b, "parameter set ids of group B (comma-separated)")
        ->required()
        ->delimiter(',');
    compare
        ->add_option(
            "--trials", form->trials,
            "trial ids every pair is predicted on (default: for each pair, the free-swing trials "
            "of the leg that the A set was not fitted on)")
        ->delimiter(',');
    compare->add_option("--metric", form->metric, "e_rms (default), e_abs, normalised_rms, ...");
    compare->add_option("--confidence", form->confidence, "confidence level, e.g. 0.95")
        ->check(CLI::Range(0.5, 0.9999));
    compare->callback([form, &context] {
      context.action = [form, &context] {
        if (form->a.size() != form->b.size()) {
          throw CliError::Usage("--params-a and --params-b must list the same number of sets (" +
                                std::to_string(form->a.size()) + " vs " +
                                std::to_string(form->b.size()) + ")");
        }
        std::vector<std::int64_t> trials;
        for (const auto& t : form->trials) trials.push_back(ParseId(t, "--trials"));
        std::vector<std::pair<std::int64_t, std::int64_t>> ids;
        for (std::size_t i = 0; i < form->a.size(); ++i) {
          ids.emplace_back(ParseId(form->a[i], "--params-a"), ParseId(form->b[i], "--params-b"));
        }
        auto client = Connect(context);
        api::ComparisonRequest request;
        if (ids.size() == 1) {
          // Two sets of one leg: one pair per trial, so the paired t-test
          // runs over the trials (docs/API.md, Jobs); by default the leg's
          // free-swing trials neither set was fitted on.
          const auto [a, b] = ids[0];
          std::vector<std::int64_t> over = trials;
          if (over.empty()) {
            const std::vector<std::int64_t> b_training =
                TrainingTrials(client->Get("/parameter-sets/" + std::to_string(b)));
            for (const auto& t : ValidationTrials(*client, a)) {
              const std::int64_t id = t.get<std::int64_t>();
              if (!Contains(b_training, id)) over.push_back(id);
            }
            if (over.empty()) {
              throw CliError::Usage("parameter sets " + std::to_string(a) + " and " +
                                    std::to_string(b) +
                                    " have no free-swing trial of their leg that neither was "
                                    "fitted on: record one or name trials with --trials");
            }
          } else {
            NoteTrainingTrials(*client, context, {a, b}, over);
          }
          for (std::int64_t t : over) request.pairs.push_back({a, b, {t}});
        } else {
          for (const auto& [a, b] : ids) {
            api::ComparisonPair pair{a, b, trials};
            if (trials.empty()) {
              pair.trial_ids = ValidationTrials(*client, a).get<std::vector<std::int64_t>>();
            } else {
              NoteTrainingTrials(*client, context, {a, b}, trials);
            }
            request.pairs.push_back(std::move(pair));
          }
        }
        if (!form->metric.empty()) request.metric = form->metric;
        if (form->confidence > 0.0) request.confidence = form->confidence;
        const json job = client->Post("/comparisons", api::ComparisonRequestToJson(request));
        const json result = WaitForJob(*client, job["id"].get<std::int64_t>());
        if (context.options.json) {
          context.out << result.dump(2) << "\n";
          return;
        }
        const std::string unit = result.value("unit", "");
        std::vector<std::vector<std::string>> rows;
        for (const auto& p : result["pairs"]) {
          const double diff = p["a_error"].get<double>() - p["b_error"].get<double>();
          rows.push_back({Cell(p["a_parameter_set_id"]), Cell(p["b_parameter_set_id"]),
                          Cell(p["subject_id"]), TrialList(p["trials"]), Fixed(p["a_error"], 4),
                          Fixed(p["b_error"], 4), Fixed(json(diff), 4)});
        }
        context.out << "metric " << Cell(result["metric"]) << " (" << unit << ")\n";
        PrintTable(context.out,
                   {"set_a", "set_b", "subject", "trials", "a_error", "b_error", "a-b"}, rows);
        const json& t = result["t_test"];
        if (!t.is_object()) {
          context.out << Cell(result.value("t_test_note", json("no paired t-test"))) << "\n";
          return;
        }
        context.out << "paired t-test:\n";
        PrintTable(context.out,
                   {"n", "mean_diff", "sd_diff", "t", "df", "p_value", "t_critical", "confidence",
                    "significant"},
                   {{Cell(t["n"]), Fixed(t["mean_difference"], 4), Fixed(t["sd_difference"], 4),
                     Fixed(t["t"], 3), Cell(t["df"]), Fixed(t["p_value"], 4),
                     Fixed(t["t_critical"], 3), Cell(t["confidence"]), Cell(t["significant"])}});
      };
    });
  }
}

}  // namespace fesbench::cli
