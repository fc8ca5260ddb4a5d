#include "model/identify_passive.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "model/contraction.h"
#include "model/parameter_set.h"
#include "model/simulate.h"
#include "model/stimulus_generators.h"
#include "model/trajectory.h"
#include "model/units.h"
#include "tests/model/identify_test_helpers.h"

namespace fesbench::model {
namespace {

using test_helpers::ColumnsOf;

TrialColumns MotorTrial(const ParameterSet& p, const Trajectory& traj) {
  SimulationOptions opt;
  opt.duration_s = traj.duration_s();
  return ColumnsOf(SimulateTrajectory(p, {}, traj, opt));
}

// Truth whose τ_ptv breakpoints lie inside the ±200 deg/s the trajectories
// reach, so every ordinate is identifiable.
ParameterSet Truth() {
  ParameterSet p = ExampleParameterSet();
  p.passive.torque_velocity =
      p.passive.torque_velocity.Resampled({-200, -100, -50, 0, 50, 100, 200});
  p.passive = ReferencePassive(p.passive);
  return p;
}

std::vector<TrialColumns> SumOfSinesTrials(const ParameterSet& p) {
  std::vector<TrialColumns> trials;
  for (std::uint64_t seed : {3u, 8u}) {
    SumOfSinesOptions o;
    o.min_deg = 12;
    o.max_deg = 108;
    o.seed = seed;
    trials.push_back(MotorTrial(p, SumOfSinesTrajectory(o)));
  }
  return trials;
}

double MaxDiff(const PiecewiseLinear& a, const PiecewiseLinear& b, double lo, double hi,
               double step) {
  double e = 0.0;
  for (double x = lo; x <= hi + 1e-9; x += step) e = std::max(e, std::abs(a(x) - b(x)));
  return e;
}

SimultaneousPassiveOptions TruthBreakpoints(const ParameterSet& p) {
  SimultaneousPassiveOptions o;
  o.angle.explicit_x = p.passive.torque_angle.x();
  o.velocity.explicit_x = p.passive.torque_velocity.x();
  return o;
}

TEST(AnthropometricInertia, Equation413) {
  EXPECT_NEAR(AnthropometricInertia(70.0, 0.45), 0.061 * 70.0 * std::pow(0.735 * 0.45, 2), 1e-12);
  EXPECT_THROW(AnthropometricInertia(0.0, 0.45), std::invalid_argument);
}

TEST(IdentifyPassiveSimultaneous, RecoversNoiseFreeCurvesAndInertia) {
  const ParameterSet p = Truth();
  const auto trials = SumOfSinesTrials(p);
  const PassiveResult r = IdentifyPassiveSimultaneous(trials, TruthBreakpoints(p));
  EXPECT_LT(MaxDiff(r.passive.torque_angle, p.passive.torque_angle, 15, 105, 0.5), 0.05);
  EXPECT_LT(MaxDiff(r.passive.torque_velocity, p.passive.torque_velocity, -150, 150, 1), 0.05);
  EXPECT_NEAR(r.passive.inertia_kgm2, p.passive.inertia_kgm2, 0.01 * p.passive.inertia_kgm2);
  EXPECT_NEAR(r.passive.torque_angle(90.0), 0.0, 1e-12);  // §6.5 referencing
  EXPECT_LT(r.report.fit_rms.at("passive_nm"), 1e-3);
  EXPECT_GT(r.report.values.at("coverage"), 0.3);
}

TEST(IdentifyPassiveSimultaneous, SkipsSamplesAboveMaxActivation) {
  // Every fifth sample carries activation 0.3 and a torque 5 N·m off: left
  // out by default (0.01), they leave the fit exact; let in, they spoil it.
  const ParameterSet p = Truth();
  auto trials = SumOfSinesTrials(p);
  for (TrialColumns& t : trials) {
    t.activation.assign(t.torque_nm.size(), 0.0);
    for (std::size_t i = 0; i < t.torque_nm.size(); i += 5) {
      t.activation[i] = 0.3;
      t.torque_nm[i] += 5.0;
    }
  }
  SimultaneousPassiveOptions o = TruthBreakpoints(p);
  const PassiveResult clean = IdentifyPassiveSimultaneous(trials, o);
  EXPECT_LT(MaxDiff(clean.passive.torque_angle, p.passive.torque_angle, 15, 105, 0.5), 0.05);
  o.max_activation = 0.5;
  const PassiveResult spoiled = IdentifyPassiveSimultaneous(trials, o);
  EXPECT_GT(spoiled.report.fit_rms.at("passive_nm"), 1.0);
}

TEST(IdentifyPassiveSimultaneous, WhiteTorqueNoiseKeepsTorqueAngleWithin03Nm) {
  const ParameterSet p = Truth();
  auto trials = SumOfSinesTrials(p);
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> noise(-0.5, 0.5);  // Fig. 6-23
  for (auto& tr : trials)
    for (double& v : tr.torque_nm) v += noise(rng);
  const PassiveResult r = IdentifyPassiveSimultaneous(trials, TruthBreakpoints(p));
  EXPECT_LT(MaxDiff(r.passive.torque_angle, p.passive.torque_angle, 15, 105, 0.5), 0.3);
  EXPECT_NEAR(r.report.fit_rms.at("passive_nm"), 0.5 / std::sqrt(3.0), 0.03);
}

TEST(IdentifyPassiveSimultaneous, HysteresisBecomesTorqueVelocityDiscontinuity) {
  // Fig. 6-21: τ_pta is 0.5 N·m higher while flexing than while extending.
  ParameterSet p = Truth();
  auto trials = SumOfSinesTrials(p);
  for (auto& tr : trials)
    for (std::size_t i = 0; i < tr.size(); ++i)
      tr.torque_nm[i] += tr.velocity_deg_s[i] > 0 ? 0.25 : (tr.velocity_deg_s[i] < 0 ? -0.25 : 0.0);
  SimultaneousPassiveOptions o = TruthBreakpoints(p);
  o.velocity.explicit_x = {-200, -100, -50, -2, 2, 50, 100, 200};
  const PassiveResult r = IdentifyPassiveSimultaneous(trials, o);
  const auto& ptv = r.passive.torque_velocity;
  const double jump = ptv(2.0) - ptv(-2.0);
  const double truth_jump = p.passive.torque_velocity(2.0) - p.passive.torque_velocity(-2.0);
  EXPECT_NEAR(jump - truth_jump, 0.5, 0.1);
  EXPECT_LT(MaxDiff(r.passive.torque_angle, p.passive.torque_angle, 15, 105, 0.5), 0.1);
}

TEST(IdentifyPassiveSimultaneous, RecoversStaticFriction) {
  // Fig. 6-22: τ_ptv with a ±0.5 N·m step across zero (over ±2 deg/s).
  ParameterSet p = Truth();
  p.passive.torque_velocity = PiecewiseLinear({-200, -100, -50, -2, 2, 50, 100, 200},
                                              {-1.6, -1.0, -0.75, -0.5, 0.5, 0.75, 1.0, 1.6});
  p.passive = ReferencePassive(p.passive);
  const auto trials = SumOfSinesTrials(p);
  const PassiveResult r = IdentifyPassiveSimultaneous(trials, TruthBreakpoints(p));
  EXPECT_LT(MaxDiff(r.passive.torque_velocity, p.passive.torque_velocity, -150, 150, 0.5), 0.05);
  EXPECT_NEAR(r.passive.torque_velocity(2) - r.passive.torque_velocity(-2), 1.0, 0.05);
}

TEST(IdentifyPassiveSimultaneous, WarnsWhenUnderDetermined) {
  const ParameterSet p = Truth();
  const auto trials = SumOfSinesTrials(p);
  SimultaneousPassiveOptions o = TruthBreakpoints(p);
  o.velocity.explicit_x = {-600, -400, 0, 400, 600};  // ±600 never reached
  const PassiveResult r = IdentifyPassiveSimultaneous(trials, o);
  EXPECT_FALSE(r.report.warnings.empty());
}

TEST(IdentifyPassiveSequential, HoldsAndConstantVelocityMoves) {
  const ParameterSet p = Truth();
  const SequentialPlan pos = PassivePositions({});
  const SequentialPlan vel = PassiveVelocities({});
  const TrialColumns tp = MotorTrial(p, pos.trajectory);
  const TrialColumns tv = MotorTrial(p, vel.trajectory);
  SequentialPassiveOptions o;
  o.body_mass_kg = 70.0;
  o.leg_length_m = 0.45;
  const PassiveResult r = IdentifyPassiveSequential(tp, tv, o);
  for (double x : r.passive.torque_angle.x()) {
    EXPECT_NEAR(r.passive.torque_angle(x), p.passive.torque_angle(x), 0.05) << x;
  }
  ASSERT_GE(r.passive.torque_velocity.size(), 16u);
  for (double v : r.passive.torque_velocity.x()) {
    // Between holds τ_pta is interpolated; the moves add that error.
    EXPECT_NEAR(r.passive.torque_velocity(v), p.passive.torque_velocity(v), 0.05) << v;
  }
  EXPECT_NEAR(r.passive.inertia_kgm2, AnthropometricInertia(70.0, 0.45), 1e-12);
}

TEST(IdentifyPassiveFreeSwing, RecoversTorqueVelocityAndInertia) {
  ParameterSet p = Truth();
  p.passive.torque_velocity = PiecewiseLinear({-300, -100, 100, 300}, {-2.2, -0.9, 0.9, 2.2});
  p.passive = ReferencePassive(p.passive);
  const SampledSignal env =
      MakeStimulus("random_binary_sparse", {{"amplitude_ma", 40}, {"seed", 5}});
  const TrialColumns tr = test_helpers::SimulatedFreeSwing(p, env);
  FreeSwingPassiveOptions o;
  o.velocity.explicit_x = p.passive.torque_velocity.x();
  const PassiveResult r = IdentifyPassiveFreeSwing(std::span(&tr, 1), p.passive.torque_angle, o);
  EXPECT_NEAR(r.passive.inertia_kgm2, p.passive.inertia_kgm2, 0.01 * p.passive.inertia_kgm2);
  const auto [vmin, vmax] = std::minmax_element(tr.velocity_deg_s.begin(), tr.velocity_deg_s.end());
  EXPECT_LT(MaxDiff(r.passive.torque_velocity, p.passive.torque_velocity, std::max(*vmin, -300.0),
                    std::min(*vmax, 300.0), 1.0),
            0.05);
  EXPECT_THROW(IdentifyPassiveFreeSwing(std::span(&tr, 1), PiecewiseLinear(), o),
               std::invalid_argument);
}

// The output error the J search minimises (fit_rms
// "free_swing_output_error_deg") is that of SimulateFreeSwing with the
// identified set from the stretch's measured first state: the passes step
// a cell's affine RK4 map where every stage stays in the cell and the four
// stages elsewhere, the same map as the simulator's up to rounding. One
// unstimulated 1.5 s swing (one stretch: no stops, no excursion cut),
// crossing τ_ptv's breakpoints and τ_pta's, its angle noisy; agreement to
// 1e-9 relative.
TEST(IdentifyPassiveFreeSwing, OutputErrorIsTheSimulatorsOverTheStretch) {
  ParameterSet p = Truth();
  SimulationOptions so;
  so.duration_s = 1.5;
  so.initial_angle_deg = 110.0;
  so.initial_velocity_deg_s = -150.0;
  TrialColumns tr = ColumnsOf(SimulateFreeSwing(p, {}, so));
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 0.02);
  for (double& th : tr.angle_deg) th += noise(rng);
  FreeSwingPassiveOptions o;
  o.min_segment_excursion_deg = 0.0;
  const PassiveResult r = IdentifyPassiveFreeSwing(std::span(&tr, 1), p.passive.torque_angle, o);
  ASSERT_EQ(r.report.values.at("free_swing_inertia_segments"), 1.0);
  ParameterSet fitted = p;
  fitted.passive = r.passive;
  SimulationOptions check = so;
  check.initial_angle_deg = tr.angle_deg.front();
  check.initial_velocity_deg_s = tr.velocity_deg_s.front();
  const SimulationResult sim = SimulateFreeSwing(fitted, {}, check);
  ASSERT_EQ(sim.size(), tr.size());
  double ss = 0.0;
  for (std::size_t i = 0; i < tr.size(); ++i) {
    ss += (sim.angle_deg[i] - tr.angle_deg[i]) * (sim.angle_deg[i] - tr.angle_deg[i]);
  }
  const double rms = std::sqrt(ss / static_cast<double>(tr.size()));
  EXPECT_NEAR(r.report.fit_rms.at("free_swing_output_error_deg"), rms, 1e-9 * rms);
  EXPECT_NEAR(r.passive.inertia_kgm2, p.passive.inertia_kgm2, 0.01 * p.passive.inertia_kgm2);
}

}  // namespace
}  // namespace fesbench::model
