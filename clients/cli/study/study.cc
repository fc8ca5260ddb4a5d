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

#include "api/parameter_set_json.h"
#include "api/trial.h"
#include "clients/cli/cli.h"
#include "clients/cli/commands.h"
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
  std::string protocol;
  json parameters;
  std::string label;  // the run's key and its (single) trial's name in the study
};
const std::vector<RunSpec> kRuns = {
    {"isometric_ramp_irc", json::object(), "isometric_ramp_irc"},
    {"isometric_step_irc", json::object(), "isometric_step_irc"},
    {"isometric_prediction", json::object(), "isometric_prediction"},
    {"passive_sequential", json::object(), "passive_sequential"},
    {"passive_simultaneous", json::object(), "passive_simultaneous"},
    {"free_swing_passive", json::object(), "free_swing_passive"},
    {"active_random_binary", json::object(), "active_random_binary"},
    {"prediction_step", json::object(), "prediction_step"},
    {"prediction_ramp", json::object(), "prediction_ramp"},
    {"prediction_sine", json::object(), "prediction_sine"},
    {"prediction_random_binary", json::object(), "prediction_random_binary_seed3"},
    {"prediction_random_binary", {{"seed", 4}}, "prediction_random_binary_seed4"},
    {"rapid_parameterisation", json::object(), "rapid_parameterisation"},
};
constexpr const char* kRapid = "rapid_parameterisation";

// The clinician chain (issue 15): the rapid set predicting each default
// prediction protocol's fresh trial. Label and trial name.
struct Input {
  std::string label;
  std::string trial;
};
const std::vector<Input> kChainInputs = {
    {"rb_seed3", "prediction_random_binary_seed3"},
    {"rb_seed4", "prediction_random_binary_seed4"},
    {"step", "prediction_step"},
    {"ramp", "prediction_ramp"},
    {"sine", "prediction_sine"},
};

// Prediction inputs of the thesis tables (§5.4.5): label and trial name.
const std::vector<Input> kInputs = {
    {"step", "prediction_step"},         {"ramp", "prediction_ramp"},
    {"sine", "prediction_sine"},         {"rb1", "active_random_binary_rb1"},
    {"rb2", "active_random_binary_rb2"},
};

// The six full-model parameter sets (3 passive methods × 2 active trains).
const std::vector<std::string> kPassiveMethods = {"sequential", "simultaneous", "free_swing"};
const std::vector<std::string> kTrains = {"rb1", "rb2"};
const std::vector<std::string> kSimplified = {"torque_generator", "single_segment",
                                              "static_gain_pwl_velocity", "parametric"};
// Isometric IRC variants (Tables 6.1, 6.2): irc method × contraction order.
struct IrcVariant {
  std::string key, irc_method;
  int order;
};
const std::vector<IrcVariant> kIrcVariants = {{"step_o3", "step", 3},
                                              {"ramp_o3", "ramp_correlation", 3},
                                              {"step_o2", "step", 2},
                                              {"ramp_o2", "ramp_correlation", 2}};

std::string SetKey(const std::string& passive, const std::string& train) {
  return passive + "_" + train;
}

void Pause(std::chrono::milliseconds d) { std::this_thread::sleep_for(d); }

// A leg's virtual subject as the server drew it (PUT /bench/virtual-subject
// {"draw_seed": N}): the truth for the tables and what the session records.
struct DrawnSubject {
  std::string family;
  std::uint64_t draw_seed = 0;
  model::ParameterSet truth;
  double threshold_ma = 0.0;
  double max_tolerated_ma = 0.0;
  double body_mass_kg = 0.0;
  double height_m = 0.0;
  double shank_length_m = 0.0;
  json as_put;  // the server's full JSON of the subject (put again to reset the bench)
};

DrawnSubject DrawSubject(ApiClient& client, std::uint64_t draw_seed, const std::string& family) {
  const json drawn =
      client.Put("/bench/virtual-subject", {{"draw_seed", draw_seed}, {"family", family}});
  DrawnSubject subject;
  subject.family = family;
  subject.draw_seed = draw_seed;
  try {
    auto truth = api::ParameterSetFromJson(drawn.at("truth"));
    if (!truth.ok()) {
      throw CliError::Server("study: the drawn subject's truth: " + truth.status().ToString());
    }
    subject.truth = std::move(truth).value();
    subject.as_put = drawn;
    subject.threshold_ma = drawn.at("threshold_ma").get<double>();
    subject.max_tolerated_ma = drawn.at("max_tolerated_ma").get<double>();
    const json& a = drawn.at("anthropometrics");
    subject.body_mass_kg = a.at("body_mass_kg").get<double>();
    subject.height_m = a.at("height_m").get<double>();
    subject.shank_length_m = a.at("shank_length_m").get<double>();
  } catch (const json::exception& e) {
    throw CliError::Server(std::string("study: the drawn subject's JSON: ") + e.what());
  }
  return subject;
}

struct LegData {
  int index = 0;
  DrawnSubject subject;
  std::int64_t session_id = 0;
  std::map<std::string, std::int64_t> trials;       // name → id
  std::map<std::string, double> bench_s;            // protocol → bench seconds
  std::map<std::string, std::int64_t> sets;         // set key → parameter set id
  std::map<std::string, std::string> set_failures;  // set key → message
  std::map<std::string, std::string> run_failures;  // run label → message
  std::map<std::string, model::ParameterSet> params;
  json rapid_provenance;                                   // the rapid set's, as stored
  std::map<std::string, std::string> prediction_failures;  // "set|input" → message
  // set key → input label → {e_rms, e_abs} (deg; isometric: N·m)
  std::map<std::string, std::map<std::string, std::pair<double, double>>> errors;
  std::map<std::string, json> plot_columns;  // "set|input" → predicted columns
  std::optional<LegControl> control;         // the tracking runs with the rapid set
};

// Polls a job to its end: the result, or the error message.
struct JobOutcome {
  json result;
  std::string error;
};
JobOutcome AwaitJob(ApiClient& client, std::int64_t job_id) {
  auto delay = std::chrono::milliseconds(5);
  for (;;) {
    const json job = client.Get("/jobs/" + std::to_string(job_id));
    const std::string state = job.value("state", "");
    if (state == "done") return {job.value("result", json()), ""};
    if (state == "failed") {
      std::string message = "failed";
      if (job.contains("error") && job["error"].is_object()) {
        message = job["error"].value("message", message);
        const std::string field = job["error"].value("field", "");
        if (!field.empty()) message = field + ": " + message;
      }
      return {json(), message};
    }
    Pause(delay);
    delay = std::min(delay * 2, std::chrono::milliseconds(100));
  }
}

JobOutcome Submit(ApiClient& client, const std::string& path, const json& body) {
  const json job = client.Post(path, body);
  return AwaitJob(client, job.at("id").get<std::int64_t>());
}

json TrialIds(const LegData& leg, const std::vector<std::string>& names) {
  json ids = json::array();
  for (const auto& name : names) {
    auto it = leg.trials.find(name);
    if (it != leg.trials.end()) ids.push_back(it->second);
  }
  return ids;
}

// One identification; stores every returned set under `keys` (by model
// order) or records the failure.
void Identify(ApiClient& client, LegData& leg, const json& request,
              const std::vector<std::string>& keys, int& failures, std::ostream& log) {
  const JobOutcome outcome = Submit(client, "/identifications", request);
  if (!outcome.error.empty()) {
    for (const auto& key : keys) leg.set_failures[key] = outcome.error;
    ++failures;
    log << "  leg " << leg.index << ": " << keys.front() << " failed: " << outcome.error << "\n";
    return;
  }
  const json& sets = outcome.result.at("parameter_sets");
  for (std::size_t i = 0; i < keys.size() && i < sets.size(); ++i) {
    leg.sets[keys[i]] = sets[i].at("id").get<std::int64_t>();
  }
}

void FetchParams(ApiClient& client, LegData& leg) {
  for (const auto& [key, id] : leg.sets) {
    const json stored = client.Get("/parameter-sets/" + std::to_string(id));
    auto parsed = api::ParameterSetFromJson(stored.at("parameters"));
    if (parsed.ok()) leg.params[key] = std::move(parsed).value();
    if (key != "rapid") continue;
    // The provenance as the server stored it: fields this client does not
    // parse (e.g. identified ranges) are kept.
    const json& parameters = stored.at("parameters");
    if (parameters.is_object() && parameters.contains("provenance")) {
      leg.rapid_provenance = parameters["provenance"];
    } else if (stored.contains("provenance")) {
      leg.rapid_provenance = stored["provenance"];
    }
  }
}

// A JSON number, or NaN for null / missing.
double NumberOr(const json& object, const char* key) {
  const auto it = object.find(key);
  return it != object.end() && it->is_number() ? it->get<double>() : kNaN;
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
  json request = {{"parameter_set_id", set->second}, {"trial_id", trial_id}};
  if (isometric) request["fit_scale"] = true;
  JobOutcome outcome;
  try {
    outcome = Submit(client, "/predictions", request);
  } catch (const CliError& e) {
    // A refusal (e.g. 409: the set cannot simulate this input) is a result.
    if (e.exit_code() != kExitServer) throw;
    outcome.error = e.what();
  }
  if (outcome.error.empty() &&
      (!outcome.result.contains("errors") || !outcome.result["errors"].is_object())) {
    outcome.error = "the prediction returned no errors";
  }
  if (!outcome.error.empty()) {
    leg.errors[key][input] = {kNaN, kNaN};
    leg.prediction_failures[key + "|" + input] = outcome.error;
    return;
  }
  const json& e = outcome.result["errors"];
  leg.errors[key][input] = {NumberOr(e, "e_rms"), NumberOr(e, "e_abs")};
  if (isometric) {
    leg.errors[key][input + "_normalised"] = {NumberOr(e, "normalised_rms"), kNaN};
    leg.errors[key][input + "_e_ave"] = {NumberOr(e, "e_ave"), kNaN};
  }
  if (keep_columns && outcome.result.contains("columns")) {
    leg.plot_columns[key + "|" + input] = outcome.result["columns"];
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
  const json subject =
      client.Post("/subjects", {{"code", code},
                                {"legs", {"right"}},
                                {"details",
                                 {{"weight_kg", vs.body_mass_kg},
                                  {"height_cm", vs.height_m * 100.0},
                                  {"shank_length_cm", vs.shank_length_m * 100.0}}}});
  const json session =
      client.Post("/subjects/" + std::to_string(subject.at("id").get<std::int64_t>()) + "/sessions",
                  {{"leg", "right"},
                   {"date", options.date},
                   {"threshold_ma", vs.threshold_ma},
                   {"max_tolerated_ma", vs.max_tolerated_ma}});
  leg.session_id = session.at("id").get<std::int64_t>();

  std::int64_t rapid_set = 0;
  std::map<std::int64_t, std::string> relabel;  // run id → its trial's study name
  for (const auto& spec : kRuns) {
    json run;
    try {
      run = RunProtocol(client, leg.session_id, spec.protocol, spec.parameters);
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
    leg.bench_s[spec.label] = run.value("bench_total_s", kNaN);
    if (spec.label != spec.protocol) relabel[run.at("run_id").get<std::int64_t>()] = spec.label;
    if (spec.protocol == kRapid && run["parameter_set_id"].is_number_integer()) {
      rapid_set = run["parameter_set_id"].get<std::int64_t>();
    }
  }
  for (const auto& trial :
       client.GetAllPages("/sessions/" + std::to_string(leg.session_id) + "/trials", "")) {
    std::string name = trial.at("name").get<std::string>();
    if (const auto run_id = trial.find("run_id"); run_id != trial.end() && run_id->is_number()) {
      const auto it = relabel.find(run_id->get<std::int64_t>());
      if (it != relabel.end()) name = it->second;
    }
    leg.trials[name] = trial.at("id").get<std::int64_t>();
  }
  if (rapid_set != 0) leg.sets["rapid"] = rapid_set;

  // 3 passive methods × 2 trains (§5.4); simultaneous first so free swing
  // can fall back to its τ_pta when no position holds were recognised.
  for (const auto& train : kTrains) {
    const std::string active = "active_random_binary_" + train;
    Identify(client, leg,
             {{"trial_ids", TrialIds(leg, {"isometric_ramp_irc", "passive_simultaneous_1",
                                           "passive_simultaneous_2", active})},
              {"passive_method", "simultaneous"}},
             {SetKey("simultaneous", train)}, failures, log);
    Identify(client, leg,
             {{"trial_ids", TrialIds(leg, {"isometric_ramp_irc", "passive_positions",
                                           "passive_velocities", active})},
              {"passive_method", "sequential"}},
             {SetKey("sequential", train)}, failures, log);
    std::vector<std::string> keys = {SetKey("free_swing", train)};
    json models = {"full"};
    if (train == "rb1") {
      for (const auto& m : kSimplified) {
        keys.push_back(m);
        models.push_back(m);
      }
    }
    json request = {{"trial_ids", TrialIds(leg, {"isometric_ramp_irc", "passive_positions",
                                                 "free_swing_passive", active})},
                    {"passive_method", "free_swing"},
                    {"models", models}};
    const JobOutcome first = Submit(client, "/identifications", request);
    if (first.error.empty()) {
      const json& sets = first.result.at("parameter_sets");
      for (std::size_t i = 0; i < keys.size() && i < sets.size(); ++i) {
        leg.sets[keys[i]] = sets[i].at("id").get<std::int64_t>();
      }
    } else if (leg.sets.count(SetKey("simultaneous", train)) != 0) {
      log << "  leg " << leg.index << ": " << keys.front() << " with the position holds failed ("
          << first.error << "); retrying with the simultaneous set's tau_pta\n";
      // τ_pta from the simultaneous set (Eq. 4.35 needs a τ_pta).
      request["trial_ids"] = TrialIds(leg, {"isometric_ramp_irc", "free_swing_passive", active});
      request["torque_angle_parameter_set_id"] = leg.sets[SetKey("simultaneous", train)];
      Identify(client, leg, request, keys, failures, log);
    } else {
      for (const auto& key : keys) leg.set_failures[key] = first.error;
      ++failures;
    }
  }
  // IRC variants for the isometric prediction (Tables 6.1, 6.2).
  for (const auto& variant : kIrcVariants) {
    Identify(client, leg,
             {{"trial_ids",
               TrialIds(leg, {"isometric_ramp_irc", "isometric_step_irc", "passive_simultaneous_1",
                              "passive_simultaneous_2", "active_random_binary_rb1"})},
              {"passive_method", "simultaneous"},
              {"irc_method", variant.irc_method},
              {"contraction_order", variant.order}},
             {"irc_" + variant.key}, failures, log);
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
  // Control with the rapid set (issue 19).
  if (const auto rapid = leg.sets.find("rapid"); rapid != leg.sets.end()) {
    leg.control = RunLegControl(client, index, family, leg.session_id, rapid->second,
                                vs.as_put, log);
  }
  log << "leg " << index << " done (" << leg.sets.size() << " parameter sets)\n" << std::flush;
  return leg;
}

// ---- tables -----------------------------------------------------------

double ErrorOf(const LegData& leg, const std::string& key, const std::string& input) {
  auto s = leg.errors.find(key);
  if (s == leg.errors.end()) return kNaN;
  auto e = s->second.find(input);
  return e == s->second.end() ? kNaN : e->second.first;
}

// A paired t-test row (Eq. 6.3) over the legs where both errors exist.
std::vector<std::string> TTestRow(const std::vector<LegData>& legs, const std::string& input,
                                  const std::string& a, const std::string& b) {
  std::vector<double> xa, xb;
  for (const auto& leg : legs) {
    const double ea = ErrorOf(leg, a, input), eb = ErrorOf(leg, b, input);
    if (std::isfinite(ea) && std::isfinite(eb)) xa.push_back(ea), xb.push_back(eb);
  }
  std::vector<std::string> row = {input, a, b};
  for (std::string& cell : TTestCells(xa, xb)) row.push_back(std::move(cell));
  return row;
}

const std::vector<std::string> kTTestHeader = {"input",  "set_a",     "set_b",      "n", "mean_a",
                                               "mean_b", "mean_diff", "sd_diff",    "t", "df",
                                               "p",      "t_crit_95", "significant"};

// An identified range from the provenance, compactly: [lo, hi] → "lo..hi",
// {curve: [lo, hi], …} → "curve lo..hi; …", anything else as JSON; "n/a"
// when the set does not record it.
std::string RangeText(const json& provenance, const char* key) {
  if (!provenance.is_object() || !provenance.contains(key) || provenance[key].is_null()) {
    return "n/a";
  }
  const auto pair = [](const json& r) -> std::string {
    if (r.is_array() && r.size() == 2 && r[0].is_number() && r[1].is_number()) {
      return Num(r[0].get<double>(), 1) + ".." + Num(r[1].get<double>(), 1);
    }
    return r.dump();
  };
  const json& range = provenance[key];
  if (!range.is_object()) return pair(range);
  std::string text;
  for (const auto& [curve, r] : range.items())
    text += (text.empty() ? "" : "; ") + curve + " " + pair(r);
  return text;
}

double RelativeErrorPct(double identified, double truth) {
  return std::isfinite(identified) && truth != 0.0 ? 100.0 * (identified - truth) / truth : kNaN;
}

// The clinician chain (issue 15): per leg, the default rapid set predicting
// the default prediction protocols' fresh trials, its J, pole and τ_scale
// errors against the truth, its identified ranges and the routine's bench
// time; then medians and worst values, over all legs and per family.
Table BuildChainTable(const std::vector<LegData>& legs) {
  Table t{"clinician_chain",
          "Clinician chain: default rapid set -> default prediction protocols (E_RMS deg), "
          "rapid set vs truth (%), bench time",
          {"leg", "family", "draw_seed"},
          {},
          "Every protocol parameter at its default (prediction_random_binary seeds 3 and 4). "
          "Each leg runs its prediction protocols before the rapid routine, then the rapid set "
          "predicts those trials (POST /predictions). Errors vs truth: (identified - truth) / "
          "truth. identified_range_*: from the rapid set's provenance (n/a if not recorded). "
          "worst: largest E_RMS, largest |error|, longest bench time. A refused or failed run or "
          "prediction is n/a with its reason in notes."};
  for (const auto& in : kChainInputs) t.header.push_back(in.label + "_e_rms_deg");
  const std::vector<std::string> numeric_tail = {"j_error_pct", "pole_error_pct",
                                                 "tau_scale_error_pct"};
  for (const auto& h : numeric_tail) t.header.push_back(h);
  for (const std::string h :
       {"identified_range_deg", "identified_range_deg_s", "rapid_bench_s", "notes"})
    t.header.push_back(h);

  // Per leg the numeric columns, in header order (E_RMS…, J, pole, τ_scale, bench).
  const auto values = [](const LegData& leg) {
    std::vector<double> v;
    for (const auto& in : kChainInputs) v.push_back(ErrorOf(leg, "rapid", in.label));
    const auto p = leg.params.find("rapid");
    const model::ParameterSet* set = p == leg.params.end() ? nullptr : &p->second;
    const model::ParameterSet& truth = leg.subject.truth;
    v.push_back(set ? RelativeErrorPct(set->passive.inertia_kgm2, truth.passive.inertia_kgm2)
                    : kNaN);
    v.push_back(set ? RelativeErrorPct(set->contraction.pole_per_s, truth.contraction.pole_per_s)
                    : kNaN);
    v.push_back(set ? RelativeErrorPct(set->active.torque_scale_nm, truth.active.torque_scale_nm)
                    : kNaN);
    const auto b = leg.bench_s.find(kRapid);
    v.push_back(b == leg.bench_s.end() ? kNaN : b->second);
    return v;
  };
  for (const auto& leg : legs) {
    const std::vector<double> v = values(leg);
    std::vector<std::string> row = {std::to_string(leg.index), leg.subject.family,
                                    std::to_string(leg.subject.draw_seed)};
    for (std::size_t i = 0; i + 1 < v.size(); ++i) row.push_back(Num(v[i], 3));
    row.push_back(RangeText(leg.rapid_provenance, "identified_range_deg"));
    row.push_back(RangeText(leg.rapid_provenance, "identified_range_deg_s"));
    row.push_back(Num(v.back(), 2));
    std::string notes;
    const auto note = [&](const std::string& text) { notes += (notes.empty() ? "" : "; ") + text; };
    for (const auto& in : kChainInputs) {
      if (auto f = leg.run_failures.find(in.trial); f != leg.run_failures.end()) {
        note(in.trial + " run: " + f->second);
      }
      if (auto f = leg.prediction_failures.find("rapid|" + in.label);
          f != leg.prediction_failures.end()) {
        note("rapid -> " + in.label + ": " + f->second);
      }
    }
    if (auto f = leg.run_failures.find(kRapid); f != leg.run_failures.end()) {
      note(std::string(kRapid) + " run: " + f->second);
    }
    row.push_back(notes);
    t.rows.push_back(row);
  }
  // Summary rows: all legs, then each family when there are several.
  std::vector<std::string> families;
  for (const auto& leg : legs)
    if (std::find(families.begin(), families.end(), leg.subject.family) == families.end())
      families.push_back(leg.subject.family);
  std::vector<std::string> groups = {"all"};
  if (families.size() > 1) groups.insert(groups.end(), families.begin(), families.end());
  for (const auto& group : groups) {
    std::vector<std::vector<double>> cols;
    int n = 0;
    for (const auto& leg : legs) {
      if (group != "all" && leg.subject.family != group) continue;
      ++n;
      const std::vector<double> v = values(leg);
      cols.resize(v.size());
      for (std::size_t i = 0; i < v.size(); ++i) cols[i].push_back(v[i]);
    }
    for (const std::string stat : {"median", "worst"}) {
      std::vector<std::string> row = {stat, group, std::to_string(n) + " legs"};
      for (std::size_t i = 0; i < cols.size(); ++i) {
        const double x = stat == "median" ? Median(cols[i]) : Worst(cols[i]);
        row.push_back(Num(x, i + 1 == cols.size() ? 2 : 3));
        if (i + 2 == cols.size()) row.insert(row.end(), {"", ""});  // the ranges
      }
      row.push_back("");
      t.rows.push_back(row);
    }
  }
  return t;
}

std::vector<Table> BuildTables(const std::vector<LegData>& legs) {
  std::vector<Table> tables;
  tables.push_back(BuildChainTable(legs));
  // 6.1 / 6.2: isometric prediction, scaled by its best-fit constant
  // (§6.1.2), judged by Eq. 6.1 (normalised RMS), Eq. 6.2 (E_AVE) and the
  // torque E_RMS (Eq. 6.9, N·m).
  {
    const std::vector<std::string> measures = {"isometric_normalised", "isometric_e_ave",
                                               "isometric"};
    Table t{"table_6_1_isometric_irc",
            "Table 6.1: isometric prediction, step IRC vs ramp-correlation IRC (paired t-test)",
            kTTestHeader,
            {},
            "3rd-order contraction dynamics for both; the prediction scaled by the best-fit "
            "constant (§6.1.2). Inputs: isometric_normalised = Eq. 6.1, isometric_e_ave = Eq. "
            "6.2, isometric = torque E_RMS (N.m)."};
    for (const auto& m : measures)
      t.rows.push_back(TTestRow(legs, m, "irc_step_o3", "irc_ramp_o3"));
    tables.push_back(t);
    Table u{"table_6_2_isometric_order",
            "Table 6.2: isometric prediction, 2nd vs 3rd order contraction dynamics (paired "
            "t-test)",
            kTTestHeader,
            {},
            "Rows per IRC method and error measure, as Table 6.1."};
    for (const auto& m : measures) {
      u.rows.push_back(TTestRow(legs, m, "irc_ramp_o2", "irc_ramp_o3"));
      u.rows.push_back(TTestRow(legs, m, "irc_step_o2", "irc_step_o3"));
    }
    tables.push_back(u);
  }
  // 6.3: inertia by method with the virtual truth.
  {
    // Sequential and rapid sets take J from the anthropometrics (Eq. 4.13,
    // §7.4.1), the thesis's "calculated" column; simultaneous (Eq. 4.31)
    // and free swing (Eq. 4.35) estimate it.
    Table t{"table_6_3_inertia",
            "Table 6.3: limb inertia by method (kg.m^2), with the virtual truth",
            {"leg", "anthropometric_eq_4_13", "simultaneous", "free_swing", "truth"},
            {},
            "anthropometric_eq_4_13: the inertia the sequential and rapid sets use, "
            "calculated from body mass and shank length (Eq. 4.13)."};
    const std::vector<std::string> keys = {"sequential_rb1", "simultaneous_rb1", "free_swing_rb1"};
    std::map<std::string, std::vector<double>> cols;
    for (const auto& leg : legs) {
      std::vector<std::string> row = {std::to_string(leg.index)};
      for (const auto& key : keys) {
        auto p = leg.params.find(key);
        const double j = p == leg.params.end() ? kNaN : p->second.passive.inertia_kgm2;
        cols[key].push_back(j);
        row.push_back(Num(j));
      }
      cols["truth"].push_back(leg.subject.truth.passive.inertia_kgm2);
      row.push_back(Num(leg.subject.truth.passive.inertia_kgm2));
      t.rows.push_back(row);
    }
    for (const std::string stat : {"mean", "sd"}) {
      std::vector<std::string> row = {stat};
      for (const std::string key :
           {"sequential_rb1", "simultaneous_rb1", "free_swing_rb1", "truth"})
        row.push_back(Num(stat == "mean" ? Mean(cols[key]) : Sd(cols[key])));
      t.rows.push_back(row);
    }
    tables.push_back(t);
  }
  // 6.4: linearised ζ and ω_n (Table 6.4).
  {
    Table t{"table_6_4_linearised",
            "Table 6.4: linearised passive dynamics about the rest angle (zeta, omega_n rad/s)",
            {"leg", "method", "rest_angle_deg", "zeta", "omega_n_rad_s"},
            {},
            ""};
    for (const auto& leg : legs) {
      std::vector<std::pair<std::string, const model::ParameterSet*>> sets;
      for (const std::string key :
           {"sequential_rb1", "simultaneous_rb1", "free_swing_rb1", "rapid"}) {
        auto p = leg.params.find(key);
        sets.emplace_back(key, p == leg.params.end() ? nullptr : &p->second);
      }
      sets.emplace_back("truth", &leg.subject.truth);
      for (const auto& [key, p] : sets) {
        std::vector<std::string> row = {std::to_string(leg.index), key};
        try {
          if (p == nullptr) throw std::invalid_argument("no set");
          // §6.9, Table 6.4: linearised about the free-hanging rest angle.
          const double rest_deg = model::PassiveRestAngle(p->passive);
          const model::PassiveLinearisation lin =
              model::LinearisePassive(p->passive, rest_deg, 0.0);
          row.insert(row.end(),
                     {Num(rest_deg, 2), Num(lin.damping_ratio), Num(lin.natural_frequency_rad_s)});
        } catch (const std::invalid_argument&) {
          row.insert(row.end(), {"n/a", "n/a", "n/a"});
        }
        t.rows.push_back(row);
      }
    }
    tables.push_back(t);
  }
  // 6.5–6.8: paired t-tests between parameter sets for each input.
  {
    Table t{"table_6_5_6_8_ttests",
            "Tables 6.5-6.8: paired t-tests of free-swing prediction E_RMS (deg) between parameter "
            "sets, per input",
            kTTestHeader,
            {},
            "Positive mean_diff: set_a has more error. significant: |t| > t_crit (95 %)."};
    for (const auto& input : kInputs) {
      for (const auto& train : kTrains) {
        t.rows.push_back(TTestRow(legs, input.label, SetKey("sequential", train),
                                  SetKey("simultaneous", train)));
        t.rows.push_back(TTestRow(legs, input.label, SetKey("simultaneous", train),
                                  SetKey("free_swing", train)));
        t.rows.push_back(
            TTestRow(legs, input.label, SetKey("sequential", train), SetKey("free_swing", train)));
      }
      for (const auto& p : kPassiveMethods)
        t.rows.push_back(TTestRow(legs, input.label, SetKey(p, "rb1"), SetKey(p, "rb2")));
      t.rows.push_back(TTestRow(legs, input.label, "rapid", "free_swing_rb1"));
    }
    tables.push_back(t);
  }
  // 6.9: full vs simplified.
  {
    Table t{"table_6_9_simplified",
            "Table 6.9: full model vs simplified models (free swing passive, RB1), E_RMS deg",
            kTTestHeader,
            {},
            ""};
    for (const auto& input : kInputs)
      for (const auto& m : kSimplified)
        t.rows.push_back(TTestRow(legs, input.label, m, "free_swing_rb1"));
    tables.push_back(t);
  }
  // Appendices J, K: per-leg errors.
  {
    Table t{"appendix_jk_per_leg_errors",
            "Appendices J and K: per-leg prediction errors (E_RMS and E_ABS, deg; isometric N.m)",
            {"leg", "set", "input", "e_rms", "e_abs"},
            {},
            ""};
    for (const auto& leg : legs)
      for (const auto& [key, inputs] : leg.errors)
        for (const auto& [input, e] : inputs)
          t.rows.push_back({std::to_string(leg.index), key, input, Num(e.first), Num(e.second)});
    tables.push_back(t);
    Table m{"mean_errors",
            "Mean E_RMS (deg) by parameter set and input over the cohort",
            {"set"},
            {},
            ""};
    for (const auto& input : kInputs) m.header.push_back(input.label);
    std::vector<std::string> keys = {"rapid"};
    for (const auto& p : kPassiveMethods)
      for (const auto& tr : kTrains) keys.push_back(SetKey(p, tr));
    for (const auto& s : kSimplified) keys.push_back(s);
    for (const auto& key : keys) {
      std::vector<std::string> row = {key};
      for (const auto& input : kInputs) {
        std::vector<double> v;
        for (const auto& leg : legs) v.push_back(ErrorOf(leg, key, input.label));
        row.push_back(Num(Mean(v), 3));
      }
      m.rows.push_back(row);
    }
    tables.push_back(m);
    // Medians: a few poorly identified sets (a knee predicted to sit on a
    // stop for seconds) weigh heavily in the means.
    Table md{"median_errors",
             "Median E_RMS (deg) by parameter set and input over the cohort",
             m.header,
             {},
             "The median is robust to the few predictions that fail badly."};
    for (const auto& key : keys) {
      std::vector<std::string> row = {key};
      for (const auto& input : kInputs) {
        std::vector<double> v;
        for (const auto& leg : legs) v.push_back(ErrorOf(leg, key, input.label));
        row.push_back(Num(Median(v), 3));
      }
      md.rows.push_back(row);
    }
    tables.push_back(md);
  }
  // §7.4.1 bench time per parameterisation.
  {
    Table t{"bench_time",
            "Bench time per parameterisation (s of bench time), §7.4.1",
            {"leg", "rapid_s", "traditional_s (step IRC + sequential passive)"},
            {},
            "Thesis: rapid < 30 s vs traditional 12.5 min (750 s)."};
    std::vector<double> rapid, traditional;
    for (const auto& leg : legs) {
      auto at = [&](const std::string& p) {
        auto it = leg.bench_s.find(p);
        return it == leg.bench_s.end() ? kNaN : it->second;
      };
      const double r = at("rapid_parameterisation");
      const double tr = at("isometric_step_irc") + at("passive_sequential");
      rapid.push_back(r);
      traditional.push_back(tr);
      t.rows.push_back({std::to_string(leg.index), Num(r, 2), Num(tr, 2)});
    }
    t.rows.push_back({"mean", Num(Mean(rapid), 2), Num(Mean(traditional), 2)});
    tables.push_back(t);
  }
  return tables;
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
        if (c != leg.plot_columns.end() && c->second.contains("angle_deg") &&
            i < c->second["angle_deg"].size()) {
          v = c->second["angle_deg"][i].get<double>();
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
    if (family != "thesis" && family != "analytic") {
      throw CliError::Usage("study: --families: unknown family '" + family +
                            "' (thesis, analytic)");
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
