// `fesbench identify`, `predict` and `compare`: the analysis jobs of the
// server (docs/MODEL.md; docs/API.md, "Jobs"; thesis ch. 4, §5.4.5, §7.4). Each submits a job,
// waits for it, and prints its result.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "api/analysis_requests.h"
#include "api/analysis_results.h"
#include "api/json_fields.h"
#include "api/parameter_set_record.h"
#include "api/session.h"
#include "api/subject.h"
#include "api/trial_summary.h"
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

// A figure with `digits` decimals; "-" when undefined.
std::string Fixed(std::optional<double> value, int digits) {
  if (!value || !std::isfinite(*value)) return "-";
  char buffer[48];
  std::snprintf(buffer, sizeof buffer, "%.*f", digits, *value);
  return buffer;
}

// A trial recorded in free swing (the knee angle is what is predicted), by
// the kind the server stored with it (api::IsFreeSwing).
bool IsFreeSwingTrial(const api::TrialSummary& trial) {
  return trial.kind && api::IsFreeSwing(*trial.kind);
}

api::StoredParameterSet GetParameterSet(ApiClient& client, std::int64_t set_id) {
  return FromServer(
      api::StoredParameterSetFromJson(client.Get("/parameter-sets/" + std::to_string(set_id))),
      "parameter set");
}

// The trials a parameter set was fitted on (its provenance): training data.
std::vector<std::int64_t> TrainingTrials(ApiClient& client, std::int64_t set_id) {
  return GetParameterSet(client, set_id).trial_ids;
}

// Submits an analysis job and waits for it: its result as sent.
json RunJob(ApiClient& client, const std::string& path, const json& body) {
  const api::JobReport job = FromServer(api::JobReportFromJson(client.Post(path, body)), "job");
  return WaitForJob(client, job.id);
}

bool Contains(const std::vector<std::int64_t>& ids, std::int64_t id) {
  return std::find(ids.begin(), ids.end(), id) != ids.end();
}

// Honest validation by default: the free-swing trials of the
// set's leg (every session of its subject) that the set was NOT fitted on.
std::vector<std::int64_t> ValidationTrials(ApiClient& client, std::int64_t set_id) {
  const api::StoredParameterSet set = GetParameterSet(client, set_id);
  std::vector<std::int64_t> kept;
  for (const auto& item :
       client.GetAllPages("/subjects/" + std::to_string(set.summary.subject_id) + "/sessions", "")) {
    const api::Session session = FromServer(api::SessionFromJson(item), "session");
    if (session.leg_id != set.summary.leg_id) continue;
    for (const auto& listed :
         client.GetAllPages("/sessions/" + std::to_string(session.id) + "/trials", "")) {
      const api::TrialSummary trial = FromServer(api::TrialSummaryFromJson(listed), "trial");
      if (IsFreeSwingTrial(trial) && !Contains(set.trial_ids, trial.id)) kept.push_back(trial.id);
    }
  }
  if (kept.empty()) {
    throw CliError::Usage(
        "parameter set " + std::to_string(set_id) +
        " has no free-swing trial of its leg that it was not fitted on (it was fitted on trials " +
        json(set.trial_ids).dump() +
        "): record one (e.g. `fesbench run start SESSION prediction_random_binary`) or name "
        "trials with --trials (training trials are then marked as such)");
  }
  return kept;
}

// A pair's trial ids, comma-separated.
std::string TrialList(const std::vector<api::TrialComparison>& trials) {
  std::string text;
  for (const auto& t : trials) text += (text.empty() ? "" : ",") + std::to_string(t.trial_id);
  return text;
}

// Says on standard error which of `trials` a set of `sets` was fitted on.
void NoteTrainingTrials(ApiClient& client, CliContext& context,
                        const std::vector<std::int64_t>& sets,
                        const std::vector<std::int64_t>& trials) {
  for (std::int64_t set : sets) {
    const std::vector<std::int64_t> training = TrainingTrials(client, set);
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
                         "IRC method, e.g. ramp_correlation (method rapid: only ramp_deconvolution_ideal)");
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
        const json answer = RunJob(*client, "/identifications", body);
        if (context.options.json) {
          context.out << answer.dump(2) << "\n";
          return;
        }
        const api::IdentificationResult result =
            FromServer(api::IdentificationResultFromJson(answer), "identification");
        for (const api::StoredFit& set : result.stored) {
          context.out << "parameter set " << set.parameter_set_id << " (version " << set.version
                      << ", model " << set.model << ")\n";
        }
        context.out << "report:\n";
        PrintObject(context.out, api::IdentifyReportToJson(result.report), 2);
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
          json results = json::array();
          std::vector<std::vector<std::string>> rows;
          for (const std::int64_t trial_id : ValidationTrials(*client, set_id)) {
            api::PredictionRequest request;
            request.parameter_set_id = set_id;
            request.trial_id = trial_id;
            request.mode = api::ParsePredictionMode(form->mode);
            api::PredictionView result =
                FromServer(api::PredictionViewFromJson(RunJob(
                               *client, "/predictions", api::PredictionRequestToJson(request))),
                           "prediction");
            result.columns.reset();
            const api::TrialSummary trial = FromServer(
                api::TrialSummaryFromJson(client->Get("/trials/" + std::to_string(trial_id))),
                "trial");
            const std::optional<api::PredictionErrors>& errors = result.errors;
            rows.push_back({std::to_string(trial_id), Cell(api::OrNull(trial.name)),
                            errors ? Fixed(errors->e_rms, 3) : "-",
                            errors ? Fixed(errors->e_abs, 3) : "-", errors ? errors->unit : "-",
                            Cell(api::OrNull(result.prediction_id))});
            results.push_back(api::PredictionViewToJson(result));
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
        api::PredictionView result =
            FromServer(api::PredictionViewFromJson(
                           RunJob(*client, "/predictions", api::PredictionRequestToJson(request))),
                       "prediction");
        const bool training = request.trial_id.has_value() &&
                              Contains(TrainingTrials(*client, set_id), *request.trial_id);
        if (!form->out_path.empty()) {
          if (!result.columns) throw CliError::Server("server: the prediction has no columns");
          api::ChannelGroup group;
          group.sample_rate_hz = result.sample_rate_hz.value_or(200.0);
          // t_s first, as every fesbench CSV; then the others by name.
          const api::PredictionColumns& c = *result.columns;
          group.Set(std::string(api::kTimeChannel), c.t_s);
          group.Set("activation", c.activation);
          group.Set("angle_deg", c.angle_deg);
          group.Set("stim_ma", c.stim_ma);
          group.Set("torque_nm", c.torque_nm);
          group.Set("velocity_deg_s", c.velocity_deg_s);
          if (const api::Status st = api::ValidateChannelGroup(group); !st.ok()) {
            throw CliError::Server("server sent an invalid prediction: " + st.ToString());
          }
          WriteOutput(context, form->out_path, api::GroupToCsv(group));
        }
        if (context.options.json) {
          result.columns.reset();
          context.out << api::PredictionViewToJson(result).dump(2) << "\n";
          return;
        }
        context.out << "prediction " << Cell(api::OrNull(result.prediction_id))
                    << ": parameter set " << result.parameter_set_id << ", "
                    << api::PredictionModeName(result.mode) << ", " << result.samples
                    << " samples\n";
        if (result.errors) {
          const api::PredictionErrors& errors = *result.errors;
          const std::string& unit = errors.unit;
          context.out << "E_RMS " << Fixed(errors.e_rms, 3) << " " << unit << "  E_ABS "
                      << Fixed(errors.e_abs, 3) << " " << unit << "  (trial "
                      << Cell(api::OrNull(result.trial_id)) << ", " << errors.channel << ", "
                      << errors.samples << " samples)\n";
          if (training) {
            context.out << "note: trial " << Cell(api::OrNull(result.trial_id))
                        << " is a training trial: parameter set " << set_id
                        << " was fitted on it, so these errors are not a validation\n";
          }
          if (result.fitted_scale) {
            context.out << "fitted scale " << Fixed(result.fitted_scale, 4)
                        << " (§6.1.2)  normalised E_RMS " << Fixed(errors.normalised_rms, 4)
                        << "  E_AVE " << Fixed(errors.e_ave, 5) << "\n";
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
            const std::vector<std::int64_t> b_training = TrainingTrials(*client, b);
            for (const std::int64_t id : ValidationTrials(*client, a)) {
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
              pair.trial_ids = ValidationTrials(*client, a);
            } else {
              NoteTrainingTrials(*client, context, {a, b}, trials);
            }
            request.pairs.push_back(std::move(pair));
          }
        }
        if (!form->metric.empty()) request.metric = form->metric;
        if (form->confidence > 0.0) request.confidence = form->confidence;
        const json answer = RunJob(*client, "/comparisons", api::ComparisonRequestToJson(request));
        if (context.options.json) {
          context.out << answer.dump(2) << "\n";
          return;
        }
        const api::ComparisonResult result =
            FromServer(api::ComparisonResultFromJson(answer), "comparison");
        std::vector<std::vector<std::string>> rows;
        for (const api::PairComparison& p : result.pairs) {
          rows.push_back({std::to_string(p.a_parameter_set_id),
                          std::to_string(p.b_parameter_set_id), std::to_string(p.subject_id),
                          TrialList(p.trials), Fixed(p.a_error, 4), Fixed(p.b_error, 4),
                          Fixed(p.a_error - p.b_error, 4)});
        }
        context.out << "metric " << result.metric << " (" << result.unit << ")\n";
        PrintTable(context.out,
                   {"set_a", "set_b", "subject", "trials", "a_error", "b_error", "a-b"}, rows);
        if (!result.test) {
          context.out << (result.test_note.empty() ? "no paired t-test" : result.test_note) << "\n";
          return;
        }
        const model::PairedTTestResult& t = *result.test;
        context.out << "paired t-test:\n";
        PrintTable(context.out,
                   {"n", "mean_diff", "sd_diff", "t", "df", "p_value", "t_critical", "confidence",
                    "significant"},
                   {{std::to_string(t.n), Fixed(t.mean_difference, 4), Fixed(t.sd_difference, 4),
                     Fixed(t.t, 3), Cell(json(t.df)), Fixed(t.p_value, 4), Fixed(t.t_critical, 3),
                     Cell(json(t.confidence)), Cell(json(t.significant))}});
      };
    });
  }
}

}  // namespace fesbench::cli
