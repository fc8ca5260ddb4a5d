// The virtual-cohort study (see study.h). Every bench action and every fit
// goes through the server's public HTTP API; only the tables' statistics
// (Eq. 6.3 paired t-tests, Table 6.4 linearisation) are computed here, with
// the model library's own functions.

#include "clients/cli/study/study.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <ostream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "api/analysis_requests.h"
#include "api/analysis_results.h"
#include "api/parameter_set_json.h"
#include "api/parameter_set_record.h"
#include "api/session.h"
#include "api/subject.h"
#include "api/trial_summary.h"
#include "api/trial.h"
#include "api/virtual_subject.h"
#include "clients/cli/cli.h"
#include "clients/cli/commands.h"
#include "clients/cli/study/cohort.h"
#include "clients/cli/study/control.h"
#include "clients/cli/study/tables.h"
#include "model/evaluation.h"
#include "model/parameter_set.h"

namespace fesbench::cli::study {

namespace {

using nlohmann::json;
namespace fs = std::filesystem;


// The runs per leg, in order (§5.2–5.4, Appendix F), every parameter at its
// default but the second prediction train's seed. Every prediction protocol
// runs before the rapid routine: the server's model gate checks a
// prediction protocol against the leg's latest parameter set, and before
// the rapid run there is none, so each leg's fresh prediction trials exist
// whatever the rapid set is like (docs/STUDY.md, method).
struct RunSpec {
  api::StartRunRequest request;
  std::string label;  // the run's key and its (single) trial's name in the study
};
const std::vector<RunSpec> kRuns = {
    {{.protocol = "isometric_ramp_irc"}, "isometric_ramp_irc"},
    {{.protocol = "isometric_step_irc"}, "isometric_step_irc"},
    {{.protocol = "isometric_prediction"}, "isometric_prediction"},
    {{.protocol = "passive_sequential"}, "passive_sequential"},
    {{.protocol = "passive_simultaneous"}, "passive_simultaneous"},
    {{.protocol = "free_swing_passive"}, "free_swing_passive"},
    {{.protocol = "active_random_binary"}, "active_random_binary"},
    {{.protocol = "prediction_step"}, "prediction_step"},
    {{.protocol = "prediction_ramp"}, "prediction_ramp"},
    {{.protocol = "prediction_sine"}, "prediction_sine"},
    {{.protocol = "prediction_random_binary"}, "prediction_random_binary_seed3"},
    {{.protocol = "prediction_random_binary", .parameters = {{"seed", 4}}},
     "prediction_random_binary_seed4"},
    {{.protocol = "rapid_parameterisation"}, "rapid_parameterisation"},
};



DrawnSubject DrawSubject(ApiClient& client, std::uint64_t draw_seed, const std::string& family) {
  const json drawn =
      client.Put("/bench/virtual-subject", {{"draw_seed", draw_seed}, {"family", family}});
  DrawnSubject subject;
  subject.family = family;
  subject.draw_seed = draw_seed;
  api::Result<api::VirtualSubject> read = api::VirtualSubjectFromJson(drawn);
  if (!read.ok()) {
    throw CliError::Server("study: the drawn subject: " + read.status().ToString());
  }
  subject.as_drawn = *std::move(read);
  const api::VirtualSubject& drawn_subject = subject.as_drawn;
  subject.truth = drawn_subject.truth;
  subject.threshold_ma = drawn_subject.threshold_ma;
  subject.max_tolerated_ma = drawn_subject.max_tolerated_ma;
  subject.body_mass_kg = drawn_subject.anthropometrics.body_mass_kg;
  subject.height_m = drawn_subject.anthropometrics.height_m;
  subject.shank_length_m = drawn_subject.anthropometrics.shank_length_m;
  return subject;
}

// Polls a job to its end: the result, or the error message.
struct JobOutcome {
  json result;
  std::string error;
};
JobOutcome AwaitStudyJob(ApiClient& client, std::int64_t job_id) {
  api::JobReport job =
      AwaitJob(client, job_id, std::chrono::milliseconds(5), std::chrono::milliseconds(100));
  if (job.state == api::JobState::kDone) return {std::move(job.result), ""};
  const api::Status& error = job.error;
  return {json(), error.field().empty() ? error.message() : error.field() + ": " + error.message()};
}

JobOutcome Submit(ApiClient& client, const std::string& path, const json& body) {
  const api::JobReport job = FromServer(api::JobReportFromJson(client.Post(path, body)), "job");
  return AwaitStudyJob(client, job.id);
}

std::vector<std::int64_t> TrialIds(const LegData& leg, const std::vector<std::string>& names) {
  std::vector<std::int64_t> ids;
  for (const auto& name : names) {
    auto it = leg.trials.find(name);
    if (it != leg.trials.end()) ids.push_back(it->second);
  }
  return ids;
}

// A thesis-method identification from `trial_ids` with `passive_method`.
api::IdentificationRequest ThesisFit(std::vector<std::int64_t> trial_ids,
                                     model::PassiveMethod passive_method) {
  api::IdentificationRequest request;
  request.trial_ids = std::move(trial_ids);
  request.passive_method = passive_method;
  return request;
}

// Stores the sets an identification returned under `keys` (by model order).
void StoreSets(LegData& leg, const std::vector<std::string>& keys, const JobOutcome& outcome) {
  const api::IdentificationResult result =
      FromServer(api::IdentificationResultFromJson(outcome.result), "identification");
  for (std::size_t i = 0; i < keys.size() && i < result.stored.size(); ++i) {
    leg.sets[keys[i]] = result.stored[i].parameter_set_id;
  }
}

// One identification; stores every returned set under `keys` (by model
// order) or records the failure.
void Identify(ApiClient& client, LegData& leg, const api::IdentificationRequest& request,
              const std::vector<std::string>& keys, int& failures, std::ostream& log) {
  const JobOutcome outcome =
      Submit(client, "/identifications", api::IdentificationRequestToJson(request));
  if (!outcome.error.empty()) {
    for (const auto& key : keys) leg.set_failures[key] = outcome.error;
    ++failures;
    log << "  leg " << leg.index << ": " << keys.front() << " failed: " << outcome.error << "\n";
    return;
  }
  StoreSets(leg, keys, outcome);
}

void FetchParams(ApiClient& client, LegData& leg) {
  for (const auto& [key, id] : leg.sets) {
    const api::StoredParameterSet stored = FromServer(
        api::StoredParameterSetFromJson(client.Get("/parameter-sets/" + std::to_string(id))),
        "parameter set");
    if (!stored.parameters) continue;
    leg.params[key] = *stored.parameters;
    if (key == "rapid") leg.rapid_provenance = stored.parameters->provenance;
  }
}

void Predict(ApiClient& client, LegData& leg, const std::string& key, const std::string& input,
             std::int64_t trial_id, bool keep_columns) {
  // The isometric prediction is scaled by its best-fit constant (§6.1.2)
  // and judged by Eqs. 6.1 and 6.2 as well (stored as extra inputs).
  const bool isometric = input == "isometric";
  auto set = leg.sets.find(key);
  if (set == leg.sets.end()) {
    leg.errors[key][input] = {kNaN, kNaN};
    return;
  }
  api::PredictionRequest request;
  request.parameter_set_id = set->second;
  request.trial_id = trial_id;
  request.fit_scale = isometric;
  JobOutcome outcome;
  try {
    outcome = Submit(client, "/predictions", api::PredictionRequestToJson(request));
  } catch (const CliError& e) {
    // A refusal (e.g. 409: the set cannot simulate this input) is a result.
    if (e.exit_code() != kExitServer) throw;
    outcome.error = e.what();
  }
  std::optional<api::PredictionView> prediction;
  if (outcome.error.empty()) {
    prediction = FromServer(api::PredictionViewFromJson(outcome.result), "prediction");
    if (!prediction->errors) outcome.error = "the prediction returned no errors";
  }
  if (!outcome.error.empty()) {
    leg.errors[key][input] = {kNaN, kNaN};
    leg.prediction_failures[key + "|" + input] = outcome.error;
    return;
  }
  const api::PredictionErrors& e = *prediction->errors;
  leg.errors[key][input] = {e.e_rms, e.e_abs};
  if (isometric) {
    leg.errors[key][input + "_normalised"] = {e.normalised_rms.value_or(kNaN), kNaN};
    leg.errors[key][input + "_e_ave"] = {e.e_ave.value_or(kNaN), kNaN};
  }
  if (keep_columns && prediction->columns) {
    leg.plot_columns[key + "|" + input] = *std::move(prediction->columns);
  }
}

LegData RunLeg(ApiClient& client, const StudyOptions& options, int index, int& failures,
               std::ostream& log) {
  LegData leg;
  leg.index = index;
  const std::string& family =
      options.families[static_cast<std::size_t>(index - 1) % options.families.size()];
  leg.subject =
      DrawSubject(client, options.seed * 1000 + static_cast<std::uint64_t>(index), family);
  const DrawnSubject& vs = leg.subject;

  // Codes are unique per server (a second study on one server gets new ones);
  // they never reach the tables.
  const std::string code =
      "V" + std::to_string(options.seed) + "-" + std::to_string(index) + "-" +
      std::to_string(std::chrono::system_clock::now().time_since_epoch().count() % 100000000);
  const json subject_answer =
      client.Post("/subjects", {{"code", code},
                                {"legs", {"right"}},
                                {"details",
                                 {{"weight_kg", vs.body_mass_kg},
                                  {"height_cm", vs.height_m * 100.0},
                                  {"shank_length_cm", vs.shank_length_m * 100.0}}}});
  const api::Subject subject =
      FromServer(api::SubjectFromJson(subject_answer), "subject");
  const json session = client.Post("/subjects/" + std::to_string(subject.id) + "/sessions",
                                   {{"leg", "right"},
                                    {"date", options.date},
                                    {"threshold_ma", vs.threshold_ma},
                                    {"max_tolerated_ma", vs.max_tolerated_ma}});
  leg.session_id = FromServer(api::SessionFromJson(session), "session").id;

  std::int64_t rapid_set = 0;
  std::map<std::int64_t, std::string> relabel;  // run id → its trial's study name
  for (const auto& spec : kRuns) {
    api::RunView run;
    try {
      run = RunProtocol(client, leg.session_id, spec.request);
    } catch (const CliError& e) {
      // A failed or refused run (e.g. the model gate's 409) costs its
      // trials or set; the fits and predictions that need them are listed
      // as failed.
      if (e.exit_code() != kExitServer) throw;
      ++failures;
      leg.run_failures[spec.label] = e.what();
      log << "  leg " << index << ": " << e.what() << "\n";
      continue;
    }
    leg.bench_s[spec.label] = run.progress.bench_total_s;
    if (spec.label != spec.request.protocol) relabel[run.run_id] = spec.label;
    if (spec.request.protocol == kRapid && run.parameter_set_id) rapid_set = *run.parameter_set_id;
  }
  for (const auto& listed :
       client.GetAllPages("/sessions/" + std::to_string(leg.session_id) + "/trials", "")) {
    const api::TrialSummary trial = FromServer(api::TrialSummaryFromJson(listed), "trial");
    std::string name = trial.name.value_or("");
    if (trial.run_id) {
      const auto it = relabel.find(*trial.run_id);
      if (it != relabel.end()) name = it->second;
    }
    leg.trials[name] = trial.id;
  }
  if (rapid_set != 0) leg.sets["rapid"] = rapid_set;

  // 3 passive methods × 2 trains (§5.4); simultaneous first so free swing
  // can fall back to its τ_pta when no position holds were recognised.
  for (const auto& train : kTrains) {
    const std::string active = "active_random_binary_" + train;
    Identify(client, leg,
             ThesisFit(TrialIds(leg, {"isometric_ramp_irc", "passive_simultaneous_1",
                                      "passive_simultaneous_2", active}),
                       model::PassiveMethod::kSimultaneous),
             {SetKey("simultaneous", train)}, failures, log);
    Identify(client, leg,
             ThesisFit(TrialIds(leg, {"isometric_ramp_irc", "passive_positions",
                                      "passive_velocities", active}),
                       model::PassiveMethod::kSequential),
             {SetKey("sequential", train)}, failures, log);
    std::vector<std::string> keys = {SetKey("free_swing", train)};
    api::IdentificationRequest request = ThesisFit(
        TrialIds(leg, {"isometric_ramp_irc", "passive_positions", "free_swing_passive", active}),
        model::PassiveMethod::kFreeSwing);
    if (train == "rb1") {
      for (const auto& m : kSimplified) {
        keys.push_back(m);
        if (const auto kind = model::ParseModelKind(m)) request.models.push_back(*kind);
      }
    }
    const JobOutcome first =
        Submit(client, "/identifications", api::IdentificationRequestToJson(request));
    if (first.error.empty()) {
      StoreSets(leg, keys, first);
    } else if (leg.sets.count(SetKey("simultaneous", train)) != 0) {
      log << "  leg " << leg.index << ": " << keys.front() << " with the position holds failed ("
          << first.error << "); retrying with the simultaneous set's tau_pta\n";
      // τ_pta from the simultaneous set (Eq. 4.35 needs a τ_pta).
      request.trial_ids = TrialIds(leg, {"isometric_ramp_irc", "free_swing_passive", active});
      request.torque_angle_parameter_set_id = leg.sets[SetKey("simultaneous", train)];
      Identify(client, leg, request, keys, failures, log);
    } else {
      for (const auto& key : keys) leg.set_failures[key] = first.error;
      ++failures;
    }
  }
  // IRC variants for the isometric prediction (Tables 6.1, 6.2).
  for (const auto& variant : kIrcVariants) {
    api::IdentificationRequest request = ThesisFit(
        TrialIds(leg, {"isometric_ramp_irc", "isometric_step_irc", "passive_simultaneous_1",
                       "passive_simultaneous_2", "active_random_binary_rb1"}),
        model::PassiveMethod::kSimultaneous);
    request.irc_method = variant.irc_method;
    request.contraction_order = variant.order;
    Identify(client, leg, request, {"irc_" + variant.key}, failures, log);
  }
  FetchParams(client, leg);

  // Predictions.
  const bool keep = index == 1;
  for (const auto& input : kInputs) {
    auto trial = leg.trials.find(input.trial);
    if (trial == leg.trials.end()) continue;
    std::vector<std::string> keys = {"rapid"};
    for (const auto& p : kPassiveMethods)
      for (const auto& t : kTrains) keys.push_back(SetKey(p, t));
    for (const auto& m : kSimplified) keys.push_back(m);
    for (const auto& key : keys) Predict(client, leg, key, input.label, trial->second, keep);
  }
  // The clinician chain: the rapid set on the fresh random-binary trials
  // (step, ramp and sine are above).
  for (const auto& input : kChainInputs) {
    const bool done = std::any_of(kInputs.begin(), kInputs.end(),
                                  [&](const Input& in) { return in.label == input.label; });
    if (done) continue;
    auto trial = leg.trials.find(input.trial);
    if (trial != leg.trials.end()) Predict(client, leg, "rapid", input.label, trial->second, false);
  }
  auto iso = leg.trials.find("isometric_prediction");
  for (const auto& variant : kIrcVariants) {
    if (iso != leg.trials.end()) {
      Predict(client, leg, "irc_" + variant.key, "isometric", iso->second, false);
    }
  }
  // Control with the rapid set (docs/STUDY.md, "Control").
  if (const auto rapid = leg.sets.find("rapid"); rapid != leg.sets.end()) {
    leg.control =
        RunLegControl(client, index, family, leg.session_id, rapid->second, vs.as_drawn, log);
  }
  log << "leg " << index << " done (" << leg.sets.size() << " parameter sets)\n" << std::flush;
  return leg;
}

// Data files and a gnuplot script for leg 1's predicted vs measured angle.
bool WritePlots(ApiClient& client, const LegData& leg, const fs::path& dir, bool run_gnuplot,
                std::string& note) {
  std::ofstream script(dir / "plots.gp");
  script << "# gnuplot script written by fesbench study: predicted vs measured knee angle, leg "
         << leg.index
         << "\nset terminal png size 900,500\nset termoption noenhanced\nset yrange [-20:140]\nset "
            "xlabel 't (s)'\n"
         << "set ylabel 'knee angle (deg flexion)'\nset key outside right\nset grid\n";
  const std::vector<std::string> shown = {"sequential_rb1", "simultaneous_rb1", "free_swing_rb1",
                                          "rapid"};
  for (const auto& input : kInputs) {
    auto trial_id = leg.trials.find(input.trial);
    if (trial_id == leg.trials.end()) continue;
    auto trial = api::TrialFromJson(client.Get("/trials/" + std::to_string(trial_id->second)));
    if (!trial.ok()) continue;
    const api::Channel* t = trial.value().FindChannel("t_s");
    const api::Channel* angle = trial.value().FindChannel("angle_deg");
    if (t == nullptr || angle == nullptr) continue;
    const std::string data = "plot_" + input.label + ".dat";
    std::ofstream out(dir / data);
    out << "# t_s measured_deg";
    for (const auto& key : shown) out << " " << key << "_deg";
    out << "\n";
    for (std::size_t i = 0; i < t->values.size(); i += 2) {  // 100 Hz is enough to draw.
      out << Num(t->values[i], 3) << " " << Num(angle->values[i], 3);
      for (const auto& key : shown) {
        auto c = leg.plot_columns.find(key + "|" + input.label);
        double v = kNaN;
        if (c != leg.plot_columns.end() && i < c->second.angle_deg.size()) {
          v = c->second.angle_deg[i];
        }
        out << " " << (std::isfinite(v) ? Num(v, 3) : "NaN");
      }
      out << "\n";
    }
    script << "set output 'plot_" << input.label << ".png'\nset title 'Leg " << leg.index
           << ", input " << input.label << ": predicted vs measured'\nplot '" << data
           << "' using 1:2 with lines lw 2 title 'measured'";
    for (std::size_t k = 0; k < shown.size(); ++k) {
      script << ", '' using 1:" << k + 3 << " with lines title '" << shown[k] << "'";
    }
    script << "\n";
  }
  script.close();
  if (!run_gnuplot) {
    note = "plots disabled (--no-plots); data files and plots.gp written";
    return false;
  }
  if (std::system("command -v gnuplot >/dev/null 2>&1") != 0) {
    note =
        "gnuplot not found on PATH (install Debian's gnuplot-nox): PNGs not drawn; data files "
        "and plots.gp written, tables complete";
    return false;
  }
  const std::string command = "cd '" + dir.string() + "' && gnuplot plots.gp";
  if (std::system(command.c_str()) != 0) {
    note = "gnuplot failed on plots.gp";
    return false;
  }
  return true;
}

}  // namespace

StudySummary RunStudy(ApiClient& client, const StudyOptions& options, std::ostream& log) {
  if (options.legs < 2) throw CliError::Usage("study: --legs must be at least 2");
  if (options.families.empty()) throw CliError::Usage("study: --families must name a family");
  for (const auto& family : options.families) {
    if (family != "thesis" && family != "analytic" && family != "plateau") {
      throw CliError::Usage("study: --families: unknown family '" + family +
                            "' (thesis, analytic, plateau)");
    }
  }
  fs::create_directories(options.output_dir);
  StudySummary summary;
  std::vector<LegData> legs;
  for (int i = 1; i <= options.legs; ++i) {
    legs.push_back(RunLeg(client, options, i, summary.identifications_failed, log));
    ++summary.legs_done;
  }
  const std::vector<Table> tables = BuildTables(legs);
  std::ofstream markdown(options.output_dir / "study.md");
  markdown << "# Virtual cohort study\n\n"
           << options.legs << " legs, seed " << options.seed << ", families";
  for (std::size_t i = 0; i < options.families.size(); ++i)
    markdown << (i ? ", " : " ") << options.families[i];
  markdown << " (in turn). Generated by `fesbench study`.\n\n";
  for (const auto& table : tables) WriteTable(options.output_dir, table, markdown);
  std::map<std::string, std::string> failures;
  for (const auto& leg : legs)
    for (const auto& [key, message] : leg.set_failures)
      failures[key] = message;  // one example message per set
  for (const auto& leg : legs)
    for (const auto& [protocol, message] : leg.run_failures)
      failures["run " + protocol + " (leg " + std::to_string(leg.index) + ")"] = message;
  if (!failures.empty()) {
    markdown << "## Runs and identifications that failed\n\n";
    for (const auto& [key, message] : failures) markdown << "- " << key << ": " << message << "\n";
    markdown << "\n";
  }
  std::vector<LegControl> control;
  for (const auto& leg : legs)
    if (leg.control) control.push_back(*leg.control);
  WriteControlChapter(control, options.output_dir, markdown);
  summary.plots_drawn =
      WritePlots(client, legs.front(), options.output_dir, options.plots, summary.plot_note);
  if (!summary.plot_note.empty()) markdown << "Plots: " << summary.plot_note << "\n";
  return summary;
}

}  // namespace fesbench::cli::study
