// Passive-only identification (model/identify_passive_only.h) against a
// known parameter set: pendulum tests simulated from it, identified with
// its J, and a swing from another release angle predicted.

#include "model/identify_passive_only.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "model/simulate.h"

namespace fesbench::model {
namespace {

// A pendulum test: the knee released at rest from `start_deg`, 100 Hz, angle
// only (as an OpenSim IK file brings it).
TrialColumns Pendulum(const ParameterSet& truth, double start_deg, double duration_s) {
  SimulationOptions o;
  o.initial_angle_deg = start_deg;
  o.duration_s = duration_s;
  o.output_rate_hz = 100.0;
  const SimulationResult sim = SimulateFreeSwing(truth, {}, o);
  TrialColumns tr;
  tr.t_s = sim.t_s;
  tr.angle_deg = sim.angle_deg;
  return tr;
}

double RmsError(const ParameterSet& p, const TrialColumns& measured) {
  SimulationOptions o;
  o.initial_angle_deg = measured.angle_deg.front();
  o.duration_s = measured.t_s.back() - measured.t_s.front();
  o.output_rate_hz = 100.0;
  const SimulationResult sim = SimulateFreeSwing(p, {}, o);
  double sum = 0.0;
  const std::size_t n = std::min(sim.angle_deg.size(), measured.size());
  for (std::size_t i = 0; i < n; ++i) {
    const double e = sim.angle_deg[i] - measured.angle_deg[i];
    sum += e * e;
  }
  return std::sqrt(sum / static_cast<double>(n));
}

TEST(IdentifyPassiveOnly, RecoversTheSwingOfAKnownKneeAndPredictsAnotherRelease) {
  const ParameterSet truth = ExampleParameterSet();
  const std::vector<TrialColumns> fit = {Pendulum(truth, 5.0, 8.0)};
  PassiveOnlyOptions o;
  o.inertia_kgm2 = truth.passive.inertia_kgm2;
  const PassiveOnlyResult r = IdentifyPassiveOnly(fit, o);

  EXPECT_TRUE(IsPassiveOnly(r.parameters));
  EXPECT_EQ(r.parameters.provenance.irc_method, "none");
  EXPECT_EQ(r.parameters.provenance.active_method, "none");
  EXPECT_DOUBLE_EQ(r.parameters.passive.inertia_kgm2, truth.passive.inertia_kgm2);
  EXPECT_DOUBLE_EQ(r.parameters.irc(40.0), 0.0);  // no current activates it

  // The fitted swing and held-out ones from 0°, 20° and 40° (releases the
  // fit never saw; 0.38°, 0.46°, 1.45° and 0.19° when written: the default
  // 9 angle breakpoints, chosen on a real recording, are coarser than this
  // knee's 10° ones).
  EXPECT_LT(RmsError(r.parameters, fit[0]), 0.6);
  EXPECT_LT(RmsError(r.parameters, Pendulum(truth, 0.0, 8.0)), 1.0);
  EXPECT_LT(RmsError(r.parameters, Pendulum(truth, 20.0, 8.0)), 2.0);
  EXPECT_LT(RmsError(r.parameters, Pendulum(truth, 40.0, 8.0)), 0.5);
  // τ_pta + τ_ptv(0) against the truth over the visited angles (both
  // referenced the same way, §6.5), within 10 % of the curve's span there.
  const CurveRange seen = r.parameters.provenance.identified_range_deg.at("tau_pta");
  double span = 0.0;
  for (double a = seen.lo; a <= seen.hi; a += 1.0) {
    span = std::max(span, std::abs(truth.passive.torque_angle(a)));
  }
  for (double a = std::max(seen.lo, 30.0); a <= std::min(seen.hi, 120.0); a += 10.0) {
    const double want = truth.passive.torque_angle(a) + truth.passive.torque_velocity(0.0);
    const double got = r.parameters.passive.torque_angle(a) +
                       r.parameters.passive.torque_velocity(0.0);
    EXPECT_NEAR(got, want, 0.1 * span) << "at " << a << "°";
  }
}

TEST(IdentifyPassiveOnly, RefusesStimulatedSwingsAndAMissingInertia) {
  const ParameterSet truth = ExampleParameterSet();
  TrialColumns tr = Pendulum(truth, 5.0, 3.0);
  PassiveOnlyOptions o;
  const std::vector<TrialColumns> one = {tr};
  EXPECT_THROW(IdentifyPassiveOnly(one, o), std::invalid_argument);  // J not given
  o.inertia_kgm2 = 0.3;
  tr.stim_ma.assign(tr.size(), 0.0);
  tr.stim_ma[10] = 30.0;
  const std::vector<TrialColumns> stimulated = {tr};
  EXPECT_THROW(IdentifyPassiveOnly(stimulated, o), std::invalid_argument);
  EXPECT_THROW(IdentifyPassiveOnly({}, o), std::invalid_argument);
}

TEST(PendulumReleaseIndex, SkipsTheHoldAndTheHandsLettingGo) {
  // Held at −5° for 1 s (with 0.05° of jitter), then falling as a parabola.
  std::vector<double> t, a;
  for (int i = 0; i < 200; ++i) {
    t.push_back(0.01 * i);
    const double s = t.back() - 1.0;
    a.push_back(s <= 0.0 ? -5.0 + 0.05 * std::sin(7.0 * i) : -5.0 + 400.0 * s * s);
  }
  const std::size_t r = PendulumReleaseIndex(t, a);
  EXPECT_NEAR(t[r], 1.08, 1e-9);  // the first sample past 2°: 400·0.08² = 2.56 > 2 ≥ 400·0.07²
  // Without the hold (released as the recording begins) it starts at once.
  const std::vector<double> swing(a.begin() + 100, a.end());
  const std::vector<double> swing_t(t.begin() + 100, t.end());
  EXPECT_EQ(PendulumReleaseIndex(swing_t, swing), 0u);
  const std::vector<double> still(200, 30.0);
  EXPECT_EQ(PendulumReleaseIndex(t, still), 0u);  // never departs: the whole trial
  EXPECT_THROW(PendulumReleaseIndex(t, std::vector<double>(3, 0.0)), std::invalid_argument);
}

TEST(IdentifyPassiveOnly, IsPassiveOnlyReadsTheProvenance) {
  ParameterSet p = ExampleParameterSet();
  EXPECT_FALSE(IsPassiveOnly(p));
  p.provenance.active_method = kNotIdentified;
  EXPECT_TRUE(IsPassiveOnly(p));
}

}  // namespace
}  // namespace fesbench::model
