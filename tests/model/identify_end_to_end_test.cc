// End to end (docs/MODEL.md): identify a full parameter set from simulated
// trials of a known leg with the thesis's protocol (§5.3–5.4), then predict
// that leg's response to a random-binary train it was not identified on.

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "model/contraction.h"
#include "model/evaluation.h"
#include "model/identify_active.h"
#include "model/identify_isometric.h"
#include "model/identify_passive.h"
#include "model/parameter_set.h"
#include "model/simulate.h"
#include "model/stimulus_generators.h"
#include "model/trajectory.h"
#include "tests/model/identify_test_helpers.h"

namespace fesbench::model {
namespace {

// Activation deliberately left out: it is recomputed from the identified model.
TrialColumns Columns(const SimulationResult& sim) {
  return test_helpers::ColumnsOf(sim, test_helpers::Activation::kLeaveOut);
}

using test_helpers::WholeEnvelope;

TEST(IdentifyEndToEnd, IdentifiedLegPredictsRandomBinaryResponseWithin1Degree) {
  const ParameterSet truth = ExampleParameterSet();
  const GeneratorParams range = {{"threshold_ma", 20}, {"max_ma", 45}};

  // Amplitudes keep this (weakly stiff) leg inside the bench's range.
  // Isometric: contraction dynamics and IRC (§5.3).
  const SampledSignal ramp_env = MakeStimulus("isometric_ramp_irc", range);
  const TrialColumns ramp = Columns(SimulateIsometric(
      truth, PulsesFromEnvelope(ramp_env, kDefaultPulseRateHz), 90.0, WholeEnvelope(ramp_env)));
  ParameterSet est;
  est.contraction = IdentifyContraction(std::span(&ramp, 1)).contraction;
  const IrcResult irc = IdentifyIrc(IrcMethod::kRampCorrelation, ramp);
  est.irc = irc.irc;

  // Passive: simultaneous least squares on two sum-of-sines trials (§5.4.2).
  std::vector<TrialColumns> motor;
  for (std::uint64_t seed : {3u, 8u}) {
    SumOfSinesOptions so;
    so.min_deg = 5;
    so.max_deg = 115;
    so.max_velocity_deg_s = 350;
    so.seed = seed;
    const SumOfSinesTrajectory traj(so);
    SimulationOptions o;
    o.duration_s = traj.duration_s();
    motor.push_back(Columns(SimulateTrajectory(truth, {}, traj, o)));
  }
  est.passive = IdentifyPassiveSimultaneous(motor).passive;

  // Active: dense random-binary free swing, f_stim from the identified
  // IRC and dynamics (§5.4.4).
  std::vector<TrialColumns> active;
  for (double seed : {11.0, 12.0}) {
    const SampledSignal env =
        MakeStimulus("random_binary_dense", {{"amplitude_ma", 26}, {"seed", seed}});
    const PulseTrain pulses = PulsesFromEnvelope(env, kDefaultPulseRateHz);
    TrialColumns tr = Columns(SimulateFreeSwing(truth, pulses, WholeEnvelope(env)));
    tr.activation = ActivationAt(est.contraction, est.irc, pulses, kDefaultPulseRateHz, tr.t_s);
    active.push_back(std::move(tr));
  }
  const ActiveResult act = IdentifyActive(active, est.passive);
  est.active = act.active;

  // Prediction of an unseen random-binary response (§5.4.5, §6.9).
  const SampledSignal test_env =
      MakeStimulus("random_binary_dense", {{"amplitude_ma", 26}, {"seed", 99}});
  const PulseTrain test_pulses = PulsesFromEnvelope(test_env, kDefaultPulseRateHz);
  const auto measured = SimulateFreeSwing(truth, test_pulses, WholeEnvelope(test_env));
  const auto predicted = SimulateFreeSwing(est, test_pulses, WholeEnvelope(test_env));
  const double rms_deg = RmsError(predicted.angle_deg, measured.angle_deg);
  EXPECT_LT(rms_deg, 1.0);
  RecordProperty("knee_angle_rms_deg", std::to_string(rms_deg));
}

}  // namespace
}  // namespace fesbench::model
