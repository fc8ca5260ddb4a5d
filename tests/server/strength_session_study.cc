// The strength at a trial's start from the session's history (docs/MODEL.md,
// "The strength at a trial's start"), measured without a server: for each
// seeded leg, ONE simulated bench runs the default session — the rapid
// routine, then prediction_random_binary, prediction_step, prediction_ramp
// and prediction_sine in turn, `rest_s` of bench time between runs — so the
// leg carries its fatigue and potentiation from run to run. Each prediction
// trial is predicted from its measured start (as POST /predictions does)
// with the rapid set, without and with the strength state propagated
// through the session's pulses to the trial's start (StrengthAtStart),
// relative to the strength of the rapid routine's free swings. Prints E_RMS
// per trial and per protocol (median, worst). Not a ctest: a measurement to
// run by hand,
//   strength_session_study [legs_per_family=8] [rest_s=30] [fatigue_factor=1]
// (fatigue_factor multiplies each leg's fatigue rate; the variants
// first_order_true* know it).
#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <iomanip>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "api/trial_kind.h"
#include "model/conditioning.h"
#include "model/evaluation.h"
#include "model/strength_history.h"
#include "server/protocols/model_gate.h"
#include "server/protocols/plan.h"
#include "server/protocols/runner.h"
#include "tests/server/runner_rig.h"
#include "tests/server/strength_session_rig.h"

namespace fesbench::server::protocols {
namespace {

struct Variant {
  std::string name;
  std::optional<model::StrengthParameters> params;
  bool normalise = true;  // relative to the rapid free swings' strength
};

using test::Erms;
using test::IsFreeSwing;
using test::Record;

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n == 0 ? 0.0 : (n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]));
}

int Main(int argc, char** argv) {
  const int legs = argc > 1 ? std::atoi(argv[1]) : 8;
  const double rest_s = argc > 2 ? std::atof(argv[2]) : 30.0;
  const double fatigue_factor = argc > 3 ? std::atof(argv[3]) : 1.0;
  const std::vector<std::string> protocols = {"prediction_random_binary", "prediction_step",
                                              "prediction_ramp", "prediction_sine"};
  VirtualSubject probe = DrawVirtualSubject(1);
  probe.fidelity.fatigue_rate_per_s *= fatigue_factor;
  const Fidelity& fid = probe.fidelity;
  std::vector<Variant> variants = {
      {"none", std::nullopt, true},
      {"riener", model::StrengthParameters::RienerPrior(), true},
      {"riener_abs", model::StrengthParameters::RienerPrior(), false},
      {"first_order_true", model::StrengthParameters::FirstOrder(fid.fatigue_rate_per_s,
                                                                 fid.fatigue_recovery_s),
       true},
      {"first_order_true_pot",
       model::StrengthParameters::FirstOrder(fid.fatigue_rate_per_s, fid.fatigue_recovery_s,
                                             fid.potentiation_max, fid.potentiation_rate_per_s,
                                             fid.potentiation_decay_s),
       true},
  };
  // errors[variant][protocol] over legs and trials.
  std::map<std::string, std::map<std::string, std::vector<double>>> errors;
  std::cout << std::fixed << std::setprecision(3);
  for (SubjectFamily family : {SubjectFamily::kThesis, SubjectFamily::kAnalytic}) {
    for (int i = 1; i <= legs; ++i) {
      VirtualSubject vs = DrawSubject(static_cast<std::uint64_t>(i), family);
      vs.fidelity.fatigue_rate_per_s *= fatigue_factor;
      test::Rig leg(vs);
      SubjectContext ctx = test::WithKnownInertia(vs);
      ProtocolRunner runner(leg.safe, &leg.log, nullptr, test::NoWatchdog());
      auto rapid_plan = MakePlan("rapid_parameterisation", {}, ctx);
      if (!rapid_plan.ok()) continue;
      const RunResult rapid = runner.Run(*rapid_plan, ctx);
      if (rapid.state != RunState::kDone || !rapid.parameter_set) {
        std::cout << SubjectFamilyName(family) << " " << i << ": rapid failed " << rapid.reason
                  << "\n";
        continue;
      }
      const model::ParameterSet& set = *rapid.parameter_set;
      std::vector<model::StimulationRecord> history;
      for (const RecordedTrial& t : rapid.trials) history.push_back(Record(t));
      ctx.parameter_set = set;
      for (const std::string& protocol : protocols) {
        leg.bench.AdvanceTo(leg.bench.Now_s() + rest_s);
        auto plan = MakePlan(protocol, {}, ctx);
        if (!plan.ok()) continue;
        ProtocolRunner r2(leg.safe, &leg.log, nullptr, test::NoWatchdog());
        const RunResult run = r2.Run(*plan, ctx);
        for (const RecordedTrial& t : run.trials) {
          if (!IsFreeSwing(t) || !t.trial.pulses) {
            history.push_back(Record(t));
            continue;
          }
          std::cout << SubjectFamilyName(family) << " " << i << " " << protocol << " "
                    << *t.trial.name << " @" << t.bench_start_s << " s:";
          for (const Variant& v : variants) {
            std::optional<model::SimulationStrength> strength;
            if (v.params) {
              const model::StrengthModel m(*v.params);
              model::SimulationStrength s;
              s.parameters = *v.params;
              s.initial = model::StrengthAtStart(m, set.irc, history, t.bench_start_s);
              if (v.normalise) {
                // The strength of the rapid routine's free swings, which set τ_scale.
                double sf = 0.0, n = 0.0;
                for (const RecordedTrial& rt : rapid.trials) {
                  if (!IsFreeSwing(rt) || !rt.trial.pulses) continue;
                  const model::StrengthTrace trace(
                      m, set.irc, rt.trial.pulses->Train(), rt.trial.pulses->pulse_rate_hz,
                      model::StrengthAtStart(m, set.irc, history, rt.bench_start_s));
                  if (auto w = trace.ActivationWeightedFactor()) sf += *w, n += 1.0;
                }
                if (n > 0.0) s.reference_factor = sf / n;
              }
              strength = s;
              if (v.name == "riener") {
                std::cout << " [s0/ref " << model::StrengthFactor(s.initial) / s.reference_factor
                          << "]";
              }
            }
            const double e = Erms(set, t, strength);
            errors[v.name][protocol].push_back(e);
            std::cout << " " << v.name << " " << e;
          }
          const LegTruth truth = leg.bench.Truth();
          std::cout << " (leg now F " << truth.fatigue << " P " << truth.potentiation << ")\n";
          history.push_back(Record(t));
        }
      }
    }
  }
  std::cout << "\nE_RMS, deg: median / worst over legs (and trials)\n";
  for (const std::string& protocol : protocols) {
    std::cout << protocol << ":";
    for (const Variant& v : variants) {
      const std::vector<double>& e = errors[v.name][protocol];
      std::cout << "  " << v.name << " " << Median(e) << " / "
                << (e.empty() ? 0.0 : *std::max_element(e.begin(), e.end())) << " (n "
                << e.size() << ")";
    }
    std::cout << "\n";
  }
  return 0;
}

}  // namespace
}  // namespace fesbench::server::protocols

int main(int argc, char** argv) { return fesbench::server::protocols::Main(argc, argv); }
