// The identifications of the virtual cohort (docs/STUDY.md: leg i is the
// server's seeded draw 1000 + i, odd legs thesis, even legs analytic) held
// against reference values recorded from the code as it was before the
// speed work of docs/ARCHITECTURE.md "Performance": a change that makes a
// fit faster must leave what it identifies where it was. The rapid figures
// were recorded again when the output-error refinement's Jacobian became
// the exact derivative of its simulation (it was a difference quotient;
// that section says by how much they moved and why), and again when the
// rapid routine's IRC became the ramp deconvolved with the identified
// contraction dynamics (docs/MODEL.md, "The rapid routine's IRC").
//
// Per leg, trials simulated by the model itself (model/simulate.h, the
// bench's stops at 10° and 110°) with the bench's sensor noise added
// (server/bench/virtual_subject.h, Fidelity defaults: 0.02° on the angle,
// 0.05 N·m on the torque, 0.05 m/s² on an accelerometer 0.28 m from the
// knee), seeded per leg; velocity and acceleration of the free swings from
// the angle by the GCV spline (§5.1), as the rapid protocol takes them:
//   - the rapid chain of benchmarks/identify_bench.cc BM_RapidChain (pole and IRC
//     from the isometric ramp, free-swing passive with τ_pta known and J by
//     output error, active fit on that passive set);
//   - the active fit on the true passive set;
//   - the simultaneous passive fit (Eq. 4.31) on a sum-of-sines motor trial;
//   - a 10 s free-swing prediction of the chain's set;
//   - the whole rapid identification (IdentifyRapid, §7.4.1 with the
//     output-error refinement) on three legs.
//
// FESBENCH_UPDATE_COHORT_REFERENCE=1 rewrites the reference file instead of
// comparing (only when an identification is meant to change; say why in the
// commit).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "model/conditioning.h"
#include "model/contraction.h"
#include "model/identify_active.h"
#include "model/identify_isometric.h"
#include "model/identify_passive.h"
#include "model/identify_rapid.h"
#include "model/simulate.h"
#include "model/stimulus_generators.h"
#include "model/trajectory.h"
#include "model/units.h"
#include "server/bench/virtual_subject.h"

namespace fesbench::model {
namespace {

constexpr int kLegs = 16;
constexpr double kPulseRateHz = 33.0;
const JointLimits kStops{10.0, 110.0};

// Named figures of one leg, each a list of numbers.
using Figures = std::map<std::string, std::vector<double>>;

// How close a figure must stay to its reference: |x − ref| ≤ 1e-6·max(|ref|,
// 1), an ordinate near zero compared on the unit scale of its curve (N·m,
// a gain, deg), not relative to itself. The fits are deterministic, and the
// speed work changes how they compute, not what they solve: a reordered
// floating-point sum moves a result by ~1e-12 of it, the free-swing J's
// minimiser (Gauss–Newton in place of golden section, in the same bracket)
// by ~1e-8; 1e-6 leaves room for that and none for a different answer.
constexpr double kRelativeTolerance = 1e-6;

void AddNoise(std::vector<double>& v, double sd, std::mt19937_64& rng) {
  std::normal_distribution<double> noise(0.0, sd);
  for (double& x : v) x += noise(rng);
}

std::vector<double> Ordinates(const PiecewiseLinear& c) { return c.y(); }

struct Leg {
  server::VirtualSubject subject;
  TrialColumns ramp, sparse, dense, motor;
  PulseTrain sparse_pulses, dense_pulses;
};

Leg MakeLeg(int i) {
  Leg leg;
  const auto seed = static_cast<std::uint64_t>(1000 + i);
  leg.subject = server::DrawSubject(
      seed, i % 2 == 1 ? server::SubjectFamily::kThesis : server::SubjectFamily::kAnalytic);
  const ParameterSet& truth = leg.subject.truth;
  std::mt19937_64 rng(seed);
  const double thr = leg.subject.threshold_ma, max_ma = leg.subject.max_tolerated_ma;

  SimulationOptions o;
  const SampledSignal ramp_env =
      MakeStimulus("isometric_ramp_irc", {{"threshold_ma", thr}, {"max_ma", max_ma}});
  o.duration_s = ramp_env.EndTime();
  const SimulationResult ramp =
      SimulateIsometric(truth, PulsesFromEnvelope(ramp_env, kPulseRateHz), 90.0, o);
  leg.ramp.t_s = ramp.t_s;
  leg.ramp.stim_ma = ramp.stim_ma;
  leg.ramp.torque_nm = ramp.torque_nm;
  AddNoise(leg.ramp.torque_nm, 0.05, rng);

  const double amplitude = thr + 0.3 * (max_ma - thr);
  const auto swing = [&](const char* name, double stim_seed, PulseTrain& pulses) {
    const SampledSignal env =
        MakeStimulus(name, {{"amplitude_ma", amplitude}, {"seed", stim_seed}});
    pulses = PulsesFromEnvelope(env, kPulseRateHz);
    SimulationOptions so;
    so.duration_s = env.EndTime();
    so.joint_limits = kStops;
    const SimulationResult r = SimulateFreeSwing(truth, pulses, so);
    TrialColumns tr;
    tr.t_s = r.t_s;
    tr.stim_ma = r.stim_ma;
    tr.angle_deg = r.angle_deg;
    AddNoise(tr.angle_deg, 0.02, rng);
    const SmoothingSplineFit fit = GcvSmoothingSpline(tr.t_s, tr.angle_deg);
    tr.velocity_deg_s = fit.first;
    tr.accel_deg_s2 = fit.second;
    return tr;
  };
  leg.sparse = swing("random_binary_sparse", 1.0, leg.sparse_pulses);
  leg.dense = swing("random_binary_dense", 2.0, leg.dense_pulses);

  SumOfSinesOptions so;
  so.min_deg = 15;
  so.max_deg = 105;
  so.seed = seed;
  const SumOfSinesTrajectory traj(so);
  SimulationOptions mo;
  mo.duration_s = traj.duration_s();
  const SimulationResult motor = SimulateTrajectory(truth, {}, traj, mo);
  leg.motor.t_s = motor.t_s;
  leg.motor.angle_deg = motor.angle_deg;
  leg.motor.velocity_deg_s = motor.velocity_deg_s;
  leg.motor.accel_deg_s2 = motor.accel_deg_s2;
  leg.motor.torque_nm = motor.torque_nm;
  leg.motor.activation = motor.activation;
  AddNoise(leg.motor.torque_nm, 0.05, rng);
  AddNoise(leg.motor.accel_deg_s2, RadToDeg(0.05 / 0.28), rng);
  return leg;
}

Figures Identify(int i, bool with_rapid) {
  Leg leg = MakeLeg(i);
  const ParameterSet& truth = leg.subject.truth;
  Figures f;

  // The rapid chain (BM_RapidChain/1).
  ParameterSet est;
  est.contraction = IdentifyContraction(std::span(&leg.ramp, 1)).contraction;
  const IrcResult irc = IdentifyIrc(IrcMethod::kRampCorrelation, leg.ramp);
  est.irc = irc.irc;
  f["pole_per_s"] = {est.contraction.pole_per_s};
  f["irc"] = Ordinates(est.irc);
  f["irc_torque_scale_nm"] = {irc.torque_scale_nm};
  leg.sparse.activation =
      ActivationAt(est.contraction, est.irc, leg.sparse_pulses, kPulseRateHz, leg.sparse.t_s);
  leg.dense.activation =
      ActivationAt(est.contraction, est.irc, leg.dense_pulses, kPulseRateHz, leg.dense.t_s);
  FreeSwingPassiveOptions fo;
  fo.joint_limits = kStops;
  const PassiveResult fs =
      IdentifyPassiveFreeSwing(std::span(&leg.sparse, 1), truth.passive.torque_angle, fo);
  est.passive = fs.passive;
  f["free_swing_inertia_kgm2"] = {fs.passive.inertia_kgm2};
  f["free_swing_tau_ptv_nm"] = Ordinates(fs.passive.torque_velocity);
  f["free_swing_output_error_deg"] = {fs.report.fit_rms.at("free_swing_output_error_deg")};
  f["free_swing_inertia_equation_error_kgm2"] = {
      fs.report.values.at("free_swing_inertia_equation_error_kgm2")};
  f["free_swing_inertia_segments"] = {fs.report.values.at("free_swing_inertia_segments")};
  const ActiveResult act = IdentifyActive(std::span(&leg.dense, 1), est.passive);
  est.active = act.active;
  f["chain_torque_scale_nm"] = {act.active.torque_scale_nm};
  f["chain_f_ata"] = Ordinates(act.active.torque_angle);
  f["chain_f_atv"] = Ordinates(act.active.torque_velocity);

  // The active fit on the true passive set (BM_Active2000).
  const ActiveResult act_truth = IdentifyActive(std::span(&leg.dense, 1), truth.passive);
  f["active_torque_scale_nm"] = {act_truth.active.torque_scale_nm};
  f["active_f_ata"] = Ordinates(act_truth.active.torque_angle);
  f["active_f_atv"] = Ordinates(act_truth.active.torque_velocity);
  f["active_log_rms"] = {act_truth.report.fit_rms.at("active_log")};

  // The simultaneous passive fit (BM_SimultaneousPassive2000).
  const PassiveResult sim = IdentifyPassiveSimultaneous(std::span(&leg.motor, 1));
  f["simultaneous_inertia_kgm2"] = {sim.passive.inertia_kgm2};
  f["simultaneous_tau_pta_nm"] = Ordinates(sim.passive.torque_angle);
  f["simultaneous_tau_ptv_nm"] = Ordinates(sim.passive.torque_velocity);
  f["simultaneous_rms_nm"] = {sim.report.fit_rms.at("passive_nm")};

  // A 10 s prediction of the chain's set (BM_FreeSwing10sRk4's kind).
  SimulationOptions po;
  po.duration_s = 10.0;
  po.joint_limits = kStops;
  const SimulationResult pred = SimulateFreeSwing(est, leg.dense_pulses, po);
  std::vector<double> every_50th;
  for (std::size_t k = 0; k < pred.size(); k += 50) every_50th.push_back(pred.angle_deg[k]);
  f["prediction_angle_deg"] = every_50th;

  if (with_rapid) {
    RapidOptions ro;
    ro.inertia_kgm2 = truth.passive.inertia_kgm2;
    ro.joint_limits = kStops;
    TrialColumns iso;
    iso.t_s = leg.ramp.t_s;
    iso.stim_ma = leg.ramp.stim_ma;
    iso.torque_nm = leg.ramp.torque_nm;
    std::vector<TrialColumns> swings(2);
    for (std::size_t k = 0; k < 2; ++k) {
      const TrialColumns& src = k == 0 ? leg.sparse : leg.dense;
      swings[k].t_s = src.t_s;
      swings[k].stim_ma = src.stim_ma;
      swings[k].angle_deg = src.angle_deg;
    }
    const RapidResult rapid = IdentifyRapid(iso, swings, ro);
    const ParameterSet& p = rapid.parameters;
    f["rapid_pole_per_s"] = {p.contraction.pole_per_s};
    f["rapid_tau_pta_nm"] = Ordinates(p.passive.torque_angle);
    f["rapid_tau_ptv_nm"] = Ordinates(p.passive.torque_velocity);
    f["rapid_torque_scale_nm"] = {p.active.torque_scale_nm};
    f["rapid_f_ata"] = Ordinates(p.active.torque_angle);
    f["rapid_f_atv"] = Ordinates(p.active.torque_velocity);
    f["rapid_output_error_deg"] = {rapid.report.fit_rms.at("output_error_deg")};
  }
  return f;
}

bool WithRapid(int i) { return i <= 3; }

TEST(IdentifyCohort, IdentifiedSetsEqualTheRecordedReference) {
  const std::string path = FESBENCH_COHORT_REFERENCE;
  std::map<std::string, Figures> legs;
  for (int i = 1; i <= kLegs; ++i) legs["leg" + std::to_string(i)] = Identify(i, WithRapid(i));

  if (const char* update = std::getenv("FESBENCH_UPDATE_COHORT_REFERENCE");
      update != nullptr && std::string(update) == "1") {
    nlohmann::json out = legs;
    std::ofstream(path) << out.dump(1) << "\n";
    GTEST_SKIP() << "reference written to " << path;
  }
  std::ifstream in(path);
  ASSERT_TRUE(in) << "no reference file " << path;
  const auto ref = nlohmann::json::parse(in).get<std::map<std::string, Figures>>();
  ASSERT_EQ(ref.size(), legs.size());
  for (const auto& [leg, figures] : legs) {
    const Figures& expected = ref.at(leg);
    ASSERT_EQ(expected.size(), figures.size()) << leg;
    for (const auto& [name, values] : figures) {
      const std::vector<double>& want = expected.at(name);
      ASSERT_EQ(want.size(), values.size()) << leg << " " << name;
      for (std::size_t k = 0; k < values.size(); ++k) {
        EXPECT_NEAR(values[k], want[k], kRelativeTolerance * std::max(std::abs(want[k]), 1.0))
            << leg << " " << name << "[" << k << "]";
      }
    }
  }
}

}  // namespace
}  // namespace fesbench::model
