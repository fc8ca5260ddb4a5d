// The study's fatigue condition (docs/STUDY.md, "Control: knee-angle
// tracking") without a server: for each seeded leg, the rapid routine
// identifies its set on a fresh simulated leg, then inverse_model and
// adaptive each track the 0.2 Hz sine 30–80° for 2 minutes on a fresh leg
// whose fatigue rate is five times its own. Prints the per-leg tracking RMS
// and the paired t-test (Eq. 6.3). Leg i is drawn as `fesbench study --seed s`
// draws it (seed 1000·s + i, the families thesis and analytic in turn). Not a
// ctest: a measurement to run by hand,
//   tracking_fatigue_study [legs=10] [study_seed=1] [set=rapid|truth] [fatigue_factor=5] [forgetting=0.999]
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <string>
#include <vector>

#include "model/evaluation.h"
#include "server/protocols/plan.h"
#include "server/protocols/runner.h"
#include "tests/server/runner_rig.h"

namespace fesbench::server::protocols {
namespace {

struct Leg {
  explicit Leg(const VirtualSubject& vs) : subject(vs), bench(subject), safe(bench, log.sink()) {}
  VirtualSubject subject;
  SimulatedBench bench;
  SafetyEventLog log;
  SafeBench safe;
};

std::optional<model::ParameterSet> RapidSet(const VirtualSubject& vs) {
  Leg leg(vs);
  SubjectContext ctx = test::WithKnownInertia(vs);
  ctx.min_angle_deg = 10.0;
  ctx.max_angle_deg = 110.0;
  auto plan = MakePlan("rapid_parameterisation", {}, ctx);
  if (!plan.ok()) return std::nullopt;
  ProtocolRunner runner(leg.safe, &leg.log, nullptr, test::NoWatchdog());
  return runner.Run(*plan, ctx).parameter_set;
}

struct Figures {
  double rms_deg = -1.0;
  double tau_scale_nm = 0.0;
  double backoffs = 0.0;
  double max_ma_s = 0.0;  // seconds commanded at the maximum after the lead-in
  std::string failure;
};

Figures Track(VirtualSubject vs, const model::ParameterSet& set, int controller,
              double fatigue_factor, double forgetting) {
  vs.fidelity.fatigue_rate_per_s *= fatigue_factor;
  Leg leg(vs);
  SubjectContext ctx = test::SessionValues(vs);
  ctx.parameter_set = set;
  Figures f;
  auto plan = MakePlan("tracking",
                       {{"controller", controller},
                        {"lo_deg", 30.0},
                        {"hi_deg", 80.0},
                        {"frequency_hz", 0.2},
                        {"duration_s", 120.0},
                        {"forgetting", forgetting}},
                       ctx);
  if (!plan.ok()) {
    f.failure = plan.status().ToString();
    return f;
  }
  ProtocolRunner runner(leg.safe, &leg.log, nullptr, test::NoWatchdog());
  const RunResult r = runner.Run(*plan, ctx);
  if (r.state != RunState::kDone) f.failure = r.reason;
  if (r.values.contains("tracking_rms_deg")) f.rms_deg = r.values.at("tracking_rms_deg");
  if (r.values.contains("tau_scale_nm")) f.tau_scale_nm = r.values.at("tau_scale_nm");
  if (r.values.contains("oscillation_backoffs")) f.backoffs = r.values.at("oscillation_backoffs");
  if (r.values.contains("max_ma_s")) f.max_ma_s = r.values.at("max_ma_s");
  // FESBENCH_TRACE=prefix writes each run's channels to prefix<controller>.csv.
  if (const char* trace = std::getenv("FESBENCH_TRACE"); trace && !r.trials.empty()) {
    const api::Trial& t = r.trials.front().trial;
    std::ofstream out(std::string(trace) + std::to_string(controller) + ".csv");
    for (const auto& c : t.channels) out << c.name << ",";
    out << "\n";
    for (std::size_t i = 0; i < t.channels.front().values.size(); ++i) {
      for (const auto& c : t.channels) out << (i < c.values.size() ? c.values[i] : 0.0) << ",";
      out << "\n";
    }
  }
  return f;
}

int Main(int argc, char** argv) {
  const int legs = argc > 1 ? std::atoi(argv[1]) : 10;
  const std::uint64_t study_seed = argc > 2 ? std::strtoull(argv[2], nullptr, 10) : 1;
  const bool truth = argc > 3 && std::string(argv[3]) == "truth";
  const double fatigue_factor = argc > 4 ? std::atof(argv[4]) : 5.0;
  const double forgetting = argc > 5 ? std::atof(argv[5]) : 0.999;  // the protocol's default
  std::vector<double> inverse, adaptive;
  std::cout << std::fixed << std::setprecision(2);
  std::cout << "leg  set_tau  inverse_model  adaptive  adaptive_final_tau  backoffs(i/a)  at_max_s(i/a)\n";
  const char* only = std::getenv("FESBENCH_LEG");  // one leg alone
  for (int index = 1; index <= legs; ++index) {
    if (only && std::atoi(only) != index) continue;
    const std::uint64_t seed = study_seed * 1000 + static_cast<std::uint64_t>(index);
    const VirtualSubject vs =
        DrawSubject(seed, index % 2 == 1 ? SubjectFamily::kThesis : SubjectFamily::kAnalytic);
    const std::optional<model::ParameterSet> set =
        truth ? std::optional<model::ParameterSet>(vs.truth) : RapidSet(vs);
    if (!set) {
      std::cout << index << "  no set\n";
      continue;
    }
    const Figures fi = Track(vs, *set, 1, fatigue_factor, forgetting);
    const Figures fa = Track(vs, *set, 2, fatigue_factor, forgetting);
    std::cout << index << "  " << set->active.torque_scale_nm << "  " << fi.rms_deg << "  "
              << fa.rms_deg << "  " << fa.tau_scale_nm << "  " << fi.backoffs << "/" << fa.backoffs << "  " << fi.max_ma_s << "/" << fa.max_ma_s
              << (fi.failure.empty() ? "" : "  inverse: " + fi.failure)
              << (fa.failure.empty() ? "" : "  adaptive: " + fa.failure) << std::endl;
    if (fi.failure.empty() && fa.failure.empty()) {
      inverse.push_back(fi.rms_deg);
      adaptive.push_back(fa.rms_deg);
    }
  }
  if (inverse.size() >= 2) {
    const model::PairedTTestResult t = model::PairedTTest(adaptive, inverse);
    double mi = 0.0, ma = 0.0, worst = 0.0;
    for (std::size_t i = 0; i < inverse.size(); ++i) {
      mi += inverse[i] / static_cast<double>(inverse.size());
      ma += adaptive[i] / static_cast<double>(adaptive.size());
      worst = std::max(worst, adaptive[i]);
    }
    std::cout << "n " << t.n << "  mean inverse_model " << mi << "  adaptive " << ma
              << "  worst adaptive " << worst << "  d " << t.mean_difference << "  t " << t.t
              << "  p " << std::setprecision(4) << t.p_value << "\n";
  }
  return 0;
}

}  // namespace
}  // namespace fesbench::server::protocols

int main(int argc, char** argv) { return fesbench::server::protocols::Main(argc, argv); }
