#include "clients/cli/study/control.h"

#include <chrono>
#include <cmath>
#include <ostream>
#include <thread>

#include "api/run.h"
#include "api/run_start.h"
#include "clients/cli/cli.h"
#include "clients/cli/commands.h"
#include "clients/cli/study/tables.h"

namespace fesbench::cli::study {
namespace {

using nlohmann::json;

const std::vector<std::string> kControllers = {"pid", "inverse_model", "adaptive"};

// A condition of the chapter: its tracking parameters (lo_deg left to its
// default, which fits the leg: docs/PROTOCOLS.md, tracking), and the fatigue rate
// the leg is given for it (0: the subject's own).
struct Condition {
  std::string name;
  api::StartRunRequest tracking;  // without the controller and the parameter set
  double fatigue_factor = 0.0;
  std::string description;
};
const std::vector<Condition>& Conditions() {
  static const std::vector<Condition> conditions = {
      {"sine",
       {.protocol = "tracking",
        .parameters = {{"hi_deg", 80}, {"frequency_hz", 0.2}, {"duration_s", 30}},
        .choices = {{"target", "sine"}}},
       0.0,
       "0.2 Hz sine from the default extended end (30°, or what the leg's set says it reaches) "
       "to 80°, 30 s"},
      {"holds",
       {.protocol = "tracking",
        .parameters = {{"hi_deg", 80}, {"duration_s", 30}},
        .choices = {{"target", "holds"}}},
       0.0,
       "holds at lo + ½, 0, ¾, ¼ of 80° − lo (lo the default extended end; 55, 30, 67.5, 42.5° "
       "on a leg that reaches 30°; 4 s each, 1 s moves), 30 s"},
      {"fatigue",
       {.protocol = "tracking",
        .parameters = {{"hi_deg", 80}, {"frequency_hz", 0.2}, {"duration_s", 120}},
        .choices = {{"target", "sine"}}},
       5.0,
       "the sine for 2 min, fatigue rate five times the leg's"},
  };
  return conditions;
}

// A figure the run decided, NaN when it has none (docs/PROTOCOLS.md, tracking).
double ValueOr(const std::map<std::string, double>& values, const char* key) {
  const auto it = values.find(key);
  return it != values.end() ? it->second : kNaN;
}

}  // namespace

api::RunView RunProtocol(ApiClient& client, std::int64_t session_id,
                         const api::StartRunRequest& request) {
  const std::string& protocol = request.protocol;
  const api::RunView started = FromServer(
      api::RunViewFromJson(client.Post("/sessions/" + std::to_string(session_id) + "/runs",
                                       api::StartRunRequestToJson(request))),
      "run");
  const std::int64_t run_id = started.run_id;
  const std::string path = "/runs/" + std::to_string(run_id);
  for (;;) {
    try {
      client.Post(path + "/heartbeat");
    } catch (const CliError&) {
      // The run may have just ended; its state below says so.
    }
    api::RunView view = FromServer(api::RunViewFromJson(client.Get(path)), "run");
    if (view.state == api::RunState::kDone) return view;
    if (api::IsFinal(view.state)) {
      throw CliError::Server("study: run " + std::to_string(run_id) + " (" + protocol + ") " +
                             std::string(api::RunStateName(view.state)) + ": " + view.reason);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
  }
}

LegControl RunLegControl(ApiClient& client, int index, const std::string& family,
                         std::int64_t session_id, std::int64_t parameter_set_id,
                         const api::VirtualSubject& subject, std::ostream& log) {
  LegControl leg;
  leg.index = index;
  leg.family = family;
  leg.parameter_set_id = parameter_set_id;
  for (const Condition& condition : Conditions()) {
    api::VirtualSubject put = subject;
    if (condition.fatigue_factor > 0.0) put.fidelity.fatigue_rate_per_s *= condition.fatigue_factor;
    for (const std::string& controller : kControllers) {
      // A fresh bench: no controller inherits another's fatigue.
      client.Put("/bench/virtual-subject", api::VirtualSubjectToJson(put));
      api::StartRunRequest request = condition.tracking;
      request.choices["controller"] = controller;
      request.parameters["parameter_set_id"] = static_cast<double>(parameter_set_id);
      TrackingFigures& f = leg.runs[condition.name][controller];
      try {
        const api::RunView run = RunProtocol(client, session_id, request);
        const std::map<std::string, double>& v = run.values;
        f.rms_deg = ValueOr(v, "tracking_rms_deg");
        f.max_error_deg = ValueOr(v, "tracking_max_error_deg");
        f.overshoot_deg = ValueOr(v, "overshoot_deg");
        f.settling_s = ValueOr(v, "settling_s");
        f.charge_mc = ValueOr(v, "charge_uc") / 1000.0;
        f.saturated_s = ValueOr(v, "saturated_s");
        f.tau_scale_nm = ValueOr(v, "tau_scale_nm");
        f.worst_overshoot_deg = ValueOr(v, "worst_overshoot_deg");
        f.worst_settling_s = ValueOr(v, "worst_settling_s");
        f.above_1hz_deg = ValueOr(v, "error_rms_above_1hz_deg");
        f.zero_ma_s = ValueOr(v, "zero_ma_s");
        f.max_ma_s = ValueOr(v, "max_ma_s");
        f.backoffs = ValueOr(v, "oscillation_backoffs");
        if (f.backoffs > 0.0) {
          log << "  leg " << index << ": tracking " << condition.name << " " << controller
              << ": " << f.backoffs << " oscillation back-off(s), RMS " << f.rms_deg
              << "°, above 1 Hz " << f.above_1hz_deg << "°\n";
        }
      } catch (const CliError& e) {
        if (e.exit_code() != kExitServer) throw;
        f.failure = e.what();
        log << "  leg " << index << ": tracking " << condition.name << " " << controller << ": "
            << e.what() << "\n";
      }
    }
  }
  client.Put("/bench/virtual-subject", api::VirtualSubjectToJson(subject));
  return leg;
}

void WriteControlChapter(const std::vector<LegControl>& legs, const std::filesystem::path& dir,
                         std::ostream& markdown) {
  markdown << "# Control: knee-angle tracking with the rapid set (§7.6.3)\n\n"
           << "Each leg's rapid parameter set drives the `tracking` protocol with its defaults "
              "(gains tuned from the set, slew limit, saturation stop); the bench is reset "
              "before every run. Conditions: ";
  for (const Condition& c : Conditions()) markdown << c.name << " = " << c.description << "; ";
  markdown << "a run the model gate refuses or that ends failed has no figures (listed "
              "below the tables).\n\n";

  Table summary{"control_summary",
                "Control: tracking per controller over the legs (RMS and largest error in deg, "
                "charge in mC)",
                {"condition", "controller", "legs run", "median RMS", "mean RMS", "worst RMS",
                 "median max error", "median overshoot", "median settling (s)", "mean charge",
                 "median saturated (s)", "refused or failed", "worst overshoot",
                 "worst settling (s)", "median RMS above 1 Hz", "worst RMS above 1 Hz",
                 "worst at 0 mA (s)", "worst at max (s)", "back-offs"},
                {},
                "Overshoot: the largest excursion past a hold in the direction of the move "
                "into it; settling: from the move's end until the knee stays within 2° of the "
                "hold (the hold's 4 s if never). Holds only; the worst columns are the worst "
                "hold of the worst leg. RMS above 1 Hz: the part of the tracking error faster "
                "than any target (a limit cycle's signature); at 0 mA / at max: seconds the "
                "controller commanded no stimulation / the maximum after the lead-in; "
                "back-offs: the loop's gain halvings on an oscillation, summed over the legs."};
  for (const Condition& c : Conditions()) {
    for (const std::string& controller : kControllers) {
      std::vector<double> rms, max_error, overshoot, settling, charge, saturated, worst_overshoot,
          worst_settling, above, zero, at_max;
      double backoffs = 0.0;
      int failed = 0;
      for (const LegControl& leg : legs) {
        const auto cond = leg.runs.find(c.name);
        if (cond == leg.runs.end()) continue;
        const auto it = cond->second.find(controller);
        if (it == cond->second.end()) continue;
        const TrackingFigures& f = it->second;
        if (!f.failure.empty()) {
          ++failed;
          continue;
        }
        rms.push_back(f.rms_deg);
        max_error.push_back(f.max_error_deg);
        overshoot.push_back(f.overshoot_deg);
        settling.push_back(f.settling_s);
        charge.push_back(f.charge_mc);
        saturated.push_back(f.saturated_s);
        worst_overshoot.push_back(f.worst_overshoot_deg);
        worst_settling.push_back(f.worst_settling_s);
        above.push_back(f.above_1hz_deg);
        zero.push_back(f.zero_ma_s);
        at_max.push_back(f.max_ma_s);
        if (std::isfinite(f.backoffs)) backoffs += f.backoffs;
      }
      summary.rows.push_back(
          {c.name, controller, std::to_string(rms.size()), Num(Median(rms), 2), Num(Mean(rms), 2),
           Num(Worst(rms), 2), Num(Median(max_error), 2), Num(Median(overshoot), 2),
           Num(Median(settling), 2), Num(Mean(charge), 1), Num(Median(saturated), 2),
           std::to_string(failed), Num(Worst(worst_overshoot), 2), Num(Worst(worst_settling), 2),
           Num(Median(above), 2), Num(Worst(above), 2), Num(Worst(zero), 2), Num(Worst(at_max), 2),
           Num(backoffs, 0)});
    }
  }
  WriteTable(dir, summary, markdown);

  Table tests{"control_ttests",
              "Control: paired t-tests of tracking RMS (Eq. 6.3; a positive mean difference: "
              "controller a tracks worse)",
              {"condition", "controller_a", "controller_b", "n", "mean_a", "mean_b", "mean_diff",
               "sd_diff", "t", "df", "p", "t_crit_95", "significant"},
              {},
              "Over the legs where both controllers ran."};
  const std::vector<std::tuple<std::string, std::string, std::string>> pairs = {
      {"sine", "pid", "inverse_model"},      {"sine", "pid", "adaptive"},
      {"sine", "inverse_model", "adaptive"}, {"holds", "pid", "inverse_model"},
      {"holds", "pid", "adaptive"},          {"holds", "inverse_model", "adaptive"},
      {"fatigue", "pid", "inverse_model"},   {"fatigue", "inverse_model", "adaptive"}};
  for (const auto& [condition, a, b] : pairs) {
    std::vector<double> xa, xb;
    for (const LegControl& leg : legs) {
      const auto cond = leg.runs.find(condition);
      if (cond == leg.runs.end()) continue;
      const auto fa = cond->second.find(a), fb = cond->second.find(b);
      if (fa == cond->second.end() || fb == cond->second.end()) continue;
      if (!fa->second.failure.empty() || !fb->second.failure.empty()) continue;
      xa.push_back(fa->second.rms_deg);
      xb.push_back(fb->second.rms_deg);
    }
    std::vector<std::string> row = {condition, a, b};
    for (std::string& cell : TTestCells(xa, xb)) row.push_back(std::move(cell));
    tests.rows.push_back(std::move(row));
  }
  WriteTable(dir, tests, markdown);

  Table per_leg{
      "control_per_leg", "Control: tracking RMS per leg (deg)", {"leg", "family"}, {}, ""};
  for (const Condition& c : Conditions())
    for (const std::string& controller : kControllers)
      per_leg.header.push_back(c.name + " " + controller);
  per_leg.header.push_back("fatigue adaptive final τ_scale (N·m)");
  std::vector<std::string> failures;
  for (const LegControl& leg : legs) {
    std::vector<std::string> row = {std::to_string(leg.index), leg.family};
    for (const Condition& c : Conditions()) {
      for (const std::string& controller : kControllers) {
        const TrackingFigures& f = leg.runs.at(c.name).at(controller);
        row.push_back(f.failure.empty() ? Num(f.rms_deg, 2) : "—");
        if (!f.failure.empty()) {
          failures.push_back("leg " + std::to_string(leg.index) + " " + c.name + " " + controller +
                             ": " + f.failure);
        }
      }
    }
    // typed-reads: not JSON (the study's own map of conditions and controllers)
    row.push_back(Num(leg.runs.at("fatigue").at("adaptive").tau_scale_nm, 2));
    per_leg.rows.push_back(std::move(row));
  }
  WriteTable(dir, per_leg, markdown);
  if (!failures.empty()) {
    markdown << "## Tracking runs refused or failed\n\n";
    for (const std::string& f : failures) markdown << "- " << f << "\n";
    markdown << "\n";
  }
}

}  // namespace fesbench::cli::study
