// The study's control conditions (docs/STUDY.md, "Control: knee-angle
// tracking") without a server: for each seeded leg, the rapid routine
// identifies its default set on a fresh simulated leg, then each controller
// asked for (inverse_model and adaptive unless told) runs `tracking` with every
// default on a fresh leg: the default sine (30 s), the default holds (30 s)
// and the default sine for 2 minutes with the leg's fatigue rate five times
// its own. Leg i is drawn as `fesbench study --seed s` draws it with the
// three families (seed 1000·s + i; thesis, analytic, plateau in turn).
// Prints one CSV line per run (the run's figures; lo_deg is the target's
// extended end the plan used, max_rate_ma_per_s its slew limit; reach_deg
// and reach80_deg: model::ReachableExtensionDeg of the set at the maximum
// with all and with 0.8 of its activation); docs/STUDY.md's tables aggregate
// them. Not a
// ctest: a measurement to run by hand,
//   tracking_control_study [legs=24] [study_seed=1] [first_leg=1] [max_rate_ma_per_s=0]
//                          [controllers=12]
// (a slew limit given to every run; 0: the default, derived from the set;
// the controllers run, by digit: 0 pid, 1 inverse_model, 2 adaptive).
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <optional>
#include <string>

#include "model/tracking.h"
#include "server/protocols/plan.h"
#include "server/protocols/runner.h"
#include "tests/server/runner_rig.h"

namespace fesbench::server::protocols {
namespace {

std::optional<model::ParameterSet> RapidSet(const VirtualSubject& vs) {
  test::Rig leg(vs);
  SubjectContext ctx = test::WithKnownInertia(vs);
  ctx.min_angle_deg = 10.0;
  ctx.max_angle_deg = 110.0;
  auto plan = MakePlan("rapid_parameterisation", {}, ctx);
  if (!plan.ok()) return std::nullopt;
  ProtocolRunner runner(leg.safe, &leg.log, nullptr, test::NoWatchdog());
  return runner.Run(*plan, ctx).parameter_set;
}

double Value(const RunResult& r, const std::string& name) {
  return r.values.contains(name) ? r.values.at(name) : -1.0;
}

void Track(int index, std::string_view family, const std::string& condition, VirtualSubject vs,
           const model::ParameterSet& set, int controller, double max_rate_ma_per_s) {
  ParameterValues values{{"controller", controller}};
  if (max_rate_ma_per_s > 0.0) values["max_rate_ma_per_s"] = max_rate_ma_per_s;
  if (condition == "holds") values["target"] = 1.0;
  if (condition == "fatigue") {
    values["duration_s"] = 120.0;
    vs.fidelity.fatigue_rate_per_s *= 5.0;
  }
  test::Rig leg(vs);
  SubjectContext ctx = test::SessionValues(vs);
  ctx.parameter_set = set;
  std::cout << index << "," << family << "," << condition << ","
            << (controller == 0 ? "pid" : controller == 1 ? "inverse_model" : "adaptive") << ",";
  auto plan = MakePlan("tracking", values, ctx);
  if (!plan.ok()) {
    std::cout << "-1,-1,-1,-1,-1,-1,-1,-1,"
              << model::ReachableExtensionDeg(set, ctx.max_tolerated_ma) << ","
              << model::ReachableExtensionDeg(set, ctx.max_tolerated_ma, 0.8)
              << ",refused: " << plan.status().message() << std::endl;
    return;
  }
  ProtocolRunner runner(leg.safe, &leg.log, nullptr, test::NoWatchdog());
  const RunResult r = runner.Run(*plan, ctx);
  // FESBENCH_TRACE=prefix writes each run's channels to
  // prefix<leg>_<condition>_<controller>.csv.
  if (const char* trace = std::getenv("FESBENCH_TRACE"); trace && !r.trials.empty()) {
    const api::Trial& t = r.trials.front().trial;
    std::ofstream out(std::string(trace) + std::to_string(index) + "_" + condition + "_" +
                      std::to_string(controller) + ".csv");
    for (const auto& c : t.channels) out << c.name << ",";
    out << "\n";
    for (std::size_t i = 0; i < t.channels.front().values.size(); ++i) {
      for (const auto& c : t.channels) out << (i < c.values.size() ? c.values[i] : 0.0) << ",";
      out << "\n";
    }
  }
  std::cout << Value(r, "tracking_rms_deg") << "," << Value(r, "error_rms_above_1hz_deg") << ","
            << Value(r, "max_ma_s") << "," << Value(r, "oscillation_backoffs") << ","
            << Value(r, "worst_overshoot_deg") << "," << Value(r, "worst_settling_s") << ","
            << plan->parameters.at("lo_deg") << "," << plan->parameters.at("max_rate_ma_per_s")
            << "," << model::ReachableExtensionDeg(set, ctx.max_tolerated_ma) << ","
            << model::ReachableExtensionDeg(set, ctx.max_tolerated_ma, 0.8) << ","
            << (r.state == RunState::kDone ? "" : "failed: " + r.reason) << std::endl;
}

int Main(int argc, char** argv) {
  const int legs = argc > 1 ? std::atoi(argv[1]) : 24;
  const std::uint64_t study_seed = argc > 2 ? std::strtoull(argv[2], nullptr, 10) : 1;
  const int first = argc > 3 ? std::atoi(argv[3]) : 1;
  const double max_rate = argc > 4 ? std::atof(argv[4]) : 0.0;
  const std::string controllers = argc > 5 ? argv[5] : "12";
  const SubjectFamily families[] = {SubjectFamily::kThesis, SubjectFamily::kAnalytic,
                                    SubjectFamily::kPlateau};
  std::cout << std::fixed << std::setprecision(3);
  std::cout << "leg,family,condition,controller,rms_deg,above_1hz_deg,max_ma_s,backoffs,"
               "worst_overshoot_deg,worst_settling_s,lo_deg,max_rate_ma_per_s,reach_deg,"
               "reach80_deg,failure\n";
  for (int index = first; index < first + legs; ++index) {
    const std::uint64_t seed = study_seed * 1000 + static_cast<std::uint64_t>(index);
    const SubjectFamily family = families[static_cast<std::size_t>(index - 1) % 3];
    const VirtualSubject vs = DrawSubject(seed, family);
    const std::optional<model::ParameterSet> set = RapidSet(vs);
    if (!set) {
      std::cout << index << "," << SubjectFamilyName(family) << ",,,,,,,,,,,,,no set" << std::endl;
      continue;
    }
    for (const char* condition : {"sine", "holds", "fatigue"}) {
      for (char c : controllers) {
        const int controller = c - '0';
        Track(index, SubjectFamilyName(family), condition, vs, *set, controller, max_rate);
      }
    }
  }
  return 0;
}

}  // namespace
}  // namespace fesbench::server::protocols

int main(int argc, char** argv) { return fesbench::server::protocols::Main(argc, argv); }
