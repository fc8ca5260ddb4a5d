// Rapid parameterisation (§7.4.1) on data simulated by the identification
// model itself (model/simulate.h), so the fit must recover the parameter
// set up to its piecewise-linear resolution.
#include "model/identify_rapid.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "model/contraction.h"
#include "model/simulate.h"
#include "model/stimulus_generators.h"
#include "model/units.h"

namespace fesbench::model {
namespace {

constexpr double kPulseRateHz = 33.0;

// A simulated trial with the envelope as its stim_ma column.
TrialColumns FreeSwing(const ParameterSet& p, const SampledSignal& env, double start_deg) {
  SimulationOptions o;
  o.initial_angle_deg = start_deg;
  o.duration_s = env.EndTime();
  const SimulationResult r = SimulateFreeSwing(p, PulsesFromEnvelope(env, kPulseRateHz), o);
  TrialColumns c;
  c.t_s = r.t_s;
  c.stim_ma = env.values;
  c.angle_deg = r.angle_deg;
  return c;
}

double RestAngle(const ParameterSet& p) {
  for (double th = 10.0; th < 110.0; th += 0.01) {
    if (p.passive.torque_angle(th) + p.passive.torque_velocity(0.0) >= 0.0) return th;
  }
  return 90.0;
}

struct Data {
  ParameterSet truth = ExampleParameterSet();
  TrialColumns isometric, passive, active;
  Data() {
    const SampledSignal iso = MakeStimulus(
        "isometric_ramp_irc",
        {{"threshold_ma", 20.0}, {"max_ma", 45.0}, {"conditioning_s", 0.0}, {"ramps", 1.0}});
    SimulationOptions o;
    o.duration_s = iso.EndTime();
    const SimulationResult r =
        SimulateIsometric(truth, PulsesFromEnvelope(iso, kPulseRateHz), 90.0, o);
    isometric.t_s = r.t_s;
    isometric.stim_ma = iso.values;
    isometric.torque_nm = r.torque_nm;
    const double rest = RestAngle(truth);
    passive = FreeSwing(
        truth, MakeStimulus("random_binary_sparse", {{"amplitude_ma", 23.0}, {"seed", 1.0}}), rest);
    active = FreeSwing(truth,
                       MakeStimulus("random_binary_dense", {{"amplitude_ma", 23.0}, {"seed", 2.0}}),
                       passive.angle_deg.back());
  }
};

TEST(TrialPulses, MatchesTheStimulatorRule) {
  TrialColumns c;
  c.t_s = {0.0, 0.005, 0.010, 0.015, 0.020};
  c.stim_ma = {0.0, 30.0, 0.0, 0.0, 0.0};
  const PulseTrain p = TrialPulses(c, kPulseRateHz);
  ASSERT_EQ(p.size(), 1u);  // a single non-zero sample is one impulse
  EXPECT_NEAR(p[0].t_s, 0.005, 1e-12);
  EXPECT_DOUBLE_EQ(p[0].stim_ma, 30.0);
  c.stim_ma.pop_back();
  EXPECT_THROW(TrialPulses(c, kPulseRateHz), std::invalid_argument);
}

TEST(AddKinematics, DifferentiatesASineWithinTolerance) {
  TrialColumns c;
  for (int i = 0; i < 400; ++i) {
    const double t = i / 200.0;
    c.t_s.push_back(t);
    c.angle_deg.push_back(60.0 + 20.0 * std::sin(2.0 * kPi * t));
  }
  AddKinematics(c);
  for (std::size_t i = 40; i < 360; ++i) {
    const double t = c.t_s[i], w = 2.0 * kPi;
    EXPECT_NEAR(c.velocity_deg_s[i], 20.0 * w * std::cos(w * t), 0.5);
    EXPECT_NEAR(c.accel_deg_s2[i], -20.0 * w * w * std::sin(w * t), 10.0);
  }
}

TEST(IdentifyPassiveKnownInertia, RecoversPassiveTorqueOfTheSimulatedLeg) {
  Data d;
  TrialColumns trials[] = {d.passive, d.active};
  for (TrialColumns& t : trials) {
    AddKinematics(t);
    std::vector<double> ts(t.t_s);
    t.activation = ActivationAt(d.truth.contraction, d.truth.irc, TrialPulses(t, kPulseRateHz),
                                kPulseRateHz, ts);
  }
  const PassiveResult r = IdentifyPassiveKnownInertia(trials, d.truth.passive.inertia_kgm2);
  std::vector<double> angles = d.passive.angle_deg;
  std::sort(angles.begin(), angles.end());
  const double lo = angles[angles.size() / 10], hi = angles[angles.size() * 9 / 10];
  ASSERT_GT(hi - lo, 15.0);  // the swing covers a range
  for (double th = lo; th <= hi; th += 1.0) {
    const double est = r.passive.torque_angle(th) + r.passive.torque_velocity(0.0);
    const double truth = d.truth.passive.torque_angle(th) + d.truth.passive.torque_velocity(0.0);
    EXPECT_NEAR(est, truth, 0.25) << th;
  }
  EXPECT_NEAR(r.passive.torque_angle(kReferenceAngleDeg), 0.0, 1e-9);  // §6.5 referencing
  EXPECT_DOUBLE_EQ(r.passive.inertia_kgm2, d.truth.passive.inertia_kgm2);
  EXPECT_THROW(IdentifyPassiveKnownInertia(trials, 0.0), std::invalid_argument);
  TrialColumns missing = trials[0];
  missing.activation.clear();
  EXPECT_THROW(IdentifyPassiveKnownInertia({&missing, 1}, 0.3), std::invalid_argument);
}

// Output error: a set whose τ_scale is 10 % high and whose damping is
// 1.5 times the truth's simulates the recorded swings with degrees of error; the
// refinement without a prior returns to the truth's response and τ_scale.
TEST(RefineOutputError, RecoversAPerturbedSetFromItsOwnSwings) {
  Data d;
  TrialColumns trials[] = {d.passive, d.active};
  for (TrialColumns& t : trials) AddKinematics(t);
  ParameterSet start = d.truth;
  start.active.torque_scale_nm *= 1.1;
  start.passive.torque_velocity = d.truth.passive.torque_velocity.Scaled(1.5);
  OutputErrorOptions o;
  o.iterations = 10;
  o.prior_weight = 0.0;
  const OutputErrorResult r = RefineOutputError(start, trials, o);
  EXPECT_GT(r.report.fit_rms.at("output_error_start_deg"), 2.0);
  EXPECT_LT(r.report.fit_rms.at("output_error_deg"), 0.1);
  EXPECT_GT(r.report.values.at("output_error_iterations"), 0.0);
  const ActiveParams truth_active = NormaliseActive(d.truth.active);
  EXPECT_NEAR(r.parameters.active.torque_scale_nm, truth_active.torque_scale_nm,
              0.03 * truth_active.torque_scale_nm);
  EXPECT_NEAR(r.parameters.passive.torque_angle(kReferenceAngleDeg), 0.0, 1e-9);  // §6.5
  EXPECT_NEAR(r.parameters.active.torque_angle(kReferenceAngleDeg), 1.0, 1e-9);   // §6.7
  // Zero iterations: the start, referenced.
  o.iterations = 0;
  const OutputErrorResult none = RefineOutputError(start, trials, o);
  EXPECT_DOUBLE_EQ(none.report.fit_rms.at("output_error_deg"),
                   none.report.fit_rms.at("output_error_start_deg"));
  o.stride = 0;
  EXPECT_THROW(RefineOutputError(start, trials, o), std::invalid_argument);
  TrialColumns no_velocity = trials[0];
  no_velocity.velocity_deg_s.clear();
  EXPECT_THROW(RefineOutputError(start, {&no_velocity, 1}), std::invalid_argument);
}

// A hold of the relaxed knee: the motor holds angle_deg, the brace reads
// offset + τ_pta(angle) + τ_ptv(0) (Eq. 4.9 at rest) with a little
// alternating noise.
TrialColumns Hold(const ParameterSet& p, double angle_deg, double offset_nm) {
  TrialColumns h;
  for (int i = 0; i < 40; ++i) {
    h.t_s.push_back(0.005 * i);
    h.angle_deg.push_back(angle_deg);
    h.torque_nm.push_back(offset_nm + p.passive.torque_angle(angle_deg) +
                          p.passive.torque_velocity(0.0) + (i % 2 == 0 ? 0.01 : -0.01));
  }
  return h;
}

// The unstimulated swing after releasing the still knee at angle_deg.
TrialColumns Release(const ParameterSet& p, double angle_deg) {
  SampledSignal off;
  off.rate_hz = 200.0;
  off.values.assign(400, 0.0);
  return FreeSwing(p, off, angle_deg);
}

TEST(InertiaFromReleases, RecoversJWhateverTheTorqueOffset) {
  const ParameterSet truth = ExampleParameterSet();
  const std::vector<TrialColumns> swings = {Release(truth, 100.0), Release(truth, 25.0)};
  const std::vector<RapidTrials::Release> releases = {{Hold(truth, 100.0, 1.3), 0},
                                                      {Hold(truth, 25.0, 1.3), 1}};
  const ReleaseInertia r = InertiaFromReleases(swings, releases);
  // J·θ̈₀ = −τ_hold at each release; the cubic over 0.16 s of the model's
  // own swing recovers it up to its truncation (measured −4.5 % on this
  // stiff example leg; −0.4 % median, ±3 % worst on the noisy, realistic
  // cohort of docs/STUDY.md, where shorter windows lose to the noise).
  EXPECT_NEAR(r.inertia_kgm2, truth.passive.inertia_kgm2, 0.06 * truth.passive.inertia_kgm2);
  ASSERT_EQ(r.accel_deg_s2.size(), 2u);
  EXPECT_LT(r.accel_deg_s2[0] * r.accel_deg_s2[1], 0.0);  // toward extension, toward flexion
  // The window ends where the knee has travelled max_travel_deg (here
  // under 15° in 0.16 s: the full window); 5° cuts both windows short,
  // within [min_window_s, window_s], and the truncation with them (−2.4 %).
  EXPECT_EQ(r.window_s, (std::vector<double>{0.16, 0.16}));
  const ReleaseInertia short_travel = InertiaFromReleases(swings, releases, 0.16, 5.0, 0.06);
  for (double w : short_travel.window_s) {
    EXPECT_GE(w, 0.06);
    EXPECT_LT(w, 0.16);
  }
  EXPECT_NEAR(short_travel.inertia_kgm2, truth.passive.inertia_kgm2,
              0.03 * truth.passive.inertia_kgm2);
  // Refused with the reason: one release, a swing that does not exist.
  EXPECT_THROW(InertiaFromReleases(swings, std::span(releases).first(1)), std::invalid_argument);
  const std::vector<RapidTrials::Release> bad = {{Hold(truth, 100.0, 0.0), 0},
                                                 {Hold(truth, 25.0, 0.0), 5}};
  EXPECT_THROW(InertiaFromReleases(swings, bad), std::invalid_argument);
}

TEST(ScaleTorques, ScalesJAndEveryTorqueTogether) {
  const ParameterSet truth = ExampleParameterSet();
  const ParameterSet low = ScaleTorques(truth, 0.8);
  EXPECT_DOUBLE_EQ(low.passive.inertia_kgm2, 0.8 * truth.passive.inertia_kgm2);
  EXPECT_DOUBLE_EQ(low.active.torque_scale_nm, 0.8 * truth.active.torque_scale_nm);
  EXPECT_DOUBLE_EQ(low.passive.torque_angle(60.0), 0.8 * truth.passive.torque_angle(60.0));
  EXPECT_DOUBLE_EQ(low.passive.torque_velocity(50.0), 0.8 * truth.passive.torque_velocity(50.0));
  EXPECT_EQ(low.active.torque_angle, truth.active.torque_angle);
  EXPECT_EQ(low.irc, truth.irc);
}

TEST(IdentifyRapid, ReleasesMeasureTheInertiaAGivenValueMissed) {
  Data d;
  RapidTrials trials;
  trials.isometric = d.isometric;
  trials.swings = {Release(d.truth, 100.0), Release(d.truth, 25.0), d.passive, d.active};
  trials.releases = {{Hold(d.truth, 100.0, 0.4), 0}, {Hold(d.truth, 25.0, 0.4), 1}};
  RapidOptions o;
  o.inertia_kgm2 = 0.85 * d.truth.passive.inertia_kgm2;  // e.g. Eq. 4.13 15 % low
  const RapidResult r = IdentifyRapid(trials, o);
  EXPECT_EQ(r.parameters.provenance.inertia_method, "releases");
  EXPECT_NEAR(r.parameters.passive.inertia_kgm2, d.truth.passive.inertia_kgm2,
              0.06 * d.truth.passive.inertia_kgm2);
  // Without releases J stays as given.
  trials.releases.clear();
  const RapidResult given = IdentifyRapid(trials, o);
  EXPECT_DOUBLE_EQ(given.parameters.passive.inertia_kgm2, o.inertia_kgm2);
  EXPECT_EQ(given.parameters.provenance.inertia_method, "");
}

TEST(IdentifyRapid, RecoversTheModelAndPredictsItsResponse) {
  Data d;
  RapidOptions o;
  o.inertia_kgm2 = d.truth.passive.inertia_kgm2;
  const RapidResult r = IdentifyRapid(d.isometric, d.passive, d.active, o);
  const ParameterSet& p = r.parameters;
  EXPECT_EQ(p.model, ModelKind::kFull);
  EXPECT_EQ(p.contraction.order, 3);
  EXPECT_NEAR(p.contraction.pole_per_s, d.truth.contraction.pole_per_s, 0.02 * 25.0);
  // Isometric torque at 90° across the range (τ_scale·R(u)·f_ata(90°)); the
  // ramp-correlation IRC runs ≈ 12 % low near max on a 4 s ramp.
  for (double u = 25.0; u <= 45.0; u += 5.0) {
    const double truth = d.truth.active.torque_scale_nm * d.truth.irc(u);
    EXPECT_NEAR(p.active.torque_scale_nm * p.irc(u) * p.active.torque_angle(90.0), truth,
                0.15 * truth + 0.3)
        << u;
  }
  EXPECT_EQ(p.provenance.passive_method, "free_swing_known_inertia");
  EXPECT_FALSE(p.provenance.fit_rms.empty());
  // The identified set predicts a fresh random-binary response.
  const TrialColumns fresh = FreeSwing(
      d.truth, MakeStimulus("random_binary_dense", {{"amplitude_ma", 23.0}, {"seed", 9.0}}),
      RestAngle(d.truth));
  SimulationOptions so;
  so.initial_angle_deg = fresh.angle_deg.front();
  so.duration_s = fresh.t_s.back() + 0.005;
  const SimulationResult sim = SimulateFreeSwing(p, TrialPulses(fresh, kPulseRateHz), so);
  double se = 0.0;
  for (std::size_t i = 0; i < fresh.size(); ++i) {
    se += std::pow(sim.angle_deg[i] - fresh.angle_deg[i], 2);
  }
  // Limited by the angles the identification trials visited (f_ata, τ_pta
  // are held beyond them): ≈ 1.05° here.
  EXPECT_LT(std::sqrt(se / static_cast<double>(fresh.size())), 1.5);
  RapidOptions bad;
  EXPECT_THROW(IdentifyRapid(d.isometric, d.passive, d.active, bad), std::invalid_argument);
}

}  // namespace
}  // namespace fesbench::model
