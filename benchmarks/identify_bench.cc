// Identification benchmarks (docs/MODEL.md, "Identification methods"): the simultaneous passive fit
// and the active fit on 2,000 samples, the ramp-correlation IRC, the GCV
// smoothing spline on 2,000 samples, the processing chain of the rapid
// protocol (§7.4.1: IRC + poles + free-swing passive + active) and the
// whole rapid identification with its output-error refinement. Data are
// simulated once, outside the timed loops.

#include <benchmark/benchmark.h>

#include <vector>

#include "model/conditioning.h"
#include "model/contraction.h"
#include "model/identify_active.h"
#include "model/identify_isometric.h"
#include "model/identify_passive.h"
#include "model/identify_rapid.h"
#include "model/parameter_set.h"
#include "model/simulate.h"
#include "model/stimulus_generators.h"
#include "model/trajectory.h"

namespace fesbench::model {
namespace {

TrialColumns Columns(const SimulationResult& sim, std::size_t n) {
  const auto cut = [n](const std::vector<double>& v) {
    return std::vector<double>(v.begin(),
                               v.begin() + static_cast<std::ptrdiff_t>(std::min(n, v.size())));
  };
  TrialColumns tr;
  tr.t_s = cut(sim.t_s);
  tr.stim_ma = cut(sim.stim_ma);
  tr.angle_deg = cut(sim.angle_deg);
  tr.velocity_deg_s = cut(sim.velocity_deg_s);
  tr.accel_deg_s2 = cut(sim.accel_deg_s2);
  tr.torque_nm = cut(sim.torque_nm);
  tr.activation = cut(sim.activation);
  return tr;
}

struct Data {
  ParameterSet truth = ExampleParameterSet();
  TrialColumns motor, ramp, sparse, dense;
  PulseTrain sparse_pulses, dense_pulses;
  Data() {
    SumOfSinesOptions so;
    so.min_deg = 5;
    so.max_deg = 115;
    const SumOfSinesTrajectory traj(so);
    SimulationOptions o;
    o.duration_s = traj.duration_s();
    motor = Columns(SimulateTrajectory(truth, {}, traj, o), 2000);
    const SampledSignal ramp_env =
        MakeStimulus("isometric_ramp_irc", {{"threshold_ma", 20}, {"max_ma", 45}});
    o.duration_s = ramp_env.EndTime();
    ramp = Columns(
        SimulateIsometric(truth, PulsesFromEnvelope(ramp_env, kDefaultPulseRateHz), 90.0, o),
        1u << 30);
    const SampledSignal s_env =
        MakeStimulus("random_binary_sparse", {{"amplitude_ma", 26}, {"seed", 1}});
    const SampledSignal d_env =
        MakeStimulus("random_binary_dense", {{"amplitude_ma", 26}, {"seed", 2}});
    sparse_pulses = PulsesFromEnvelope(s_env, kDefaultPulseRateHz);
    dense_pulses = PulsesFromEnvelope(d_env, kDefaultPulseRateHz);
    o.duration_s = s_env.EndTime();
    sparse = Columns(SimulateFreeSwing(truth, sparse_pulses, o), 2000);
    o.duration_s = d_env.EndTime();
    dense = Columns(SimulateFreeSwing(truth, dense_pulses, o), 2000);
  }
};

const Data& GetData() {
  static const Data data;
  return data;
}

void BM_SimultaneousPassive2000(benchmark::State& state) {
  const Data& d = GetData();
  for (auto _ : state)
    benchmark::DoNotOptimize(IdentifyPassiveSimultaneous(std::span(&d.motor, 1)));
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(d.motor.size()));
}
BENCHMARK(BM_SimultaneousPassive2000)->Unit(benchmark::kMicrosecond);

void BM_Active2000(benchmark::State& state) {
  const Data& d = GetData();
  for (auto _ : state)
    benchmark::DoNotOptimize(IdentifyActive(std::span(&d.dense, 1), d.truth.passive));
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(d.dense.size()));
}
BENCHMARK(BM_Active2000)->Unit(benchmark::kMicrosecond);

void BM_RampCorrelationIrc(benchmark::State& state) {
  const Data& d = GetData();
  for (auto _ : state) benchmark::DoNotOptimize(IdentifyIrc(IrcMethod::kRampCorrelation, d.ramp));
}
BENCHMARK(BM_RampCorrelationIrc)->Unit(benchmark::kMicrosecond);

void BM_GcvSpline2000(benchmark::State& state) {
  const Data& d = GetData();
  for (auto _ : state) benchmark::DoNotOptimize(GcvSmoothingSpline(d.dense.t_s, d.dense.angle_deg));
}
BENCHMARK(BM_GcvSpline2000)->Unit(benchmark::kMicrosecond);

// The rapid protocol's processing (§7.4.1): pole and IRC from the ramp
// trial, f_stim of both free-swing trials from them, τ_ptv and J by free
// swing (τ_pta known), then the active fit. state.range(0) = 1 also derives
// velocity and acceleration of both free-swing trials by GCV spline (no
// accelerometer).
void BM_RapidChain(benchmark::State& state) {
  const Data& d = GetData();
  const bool gcv = state.range(0) != 0;
  for (auto _ : state) {
    ParameterSet est;
    est.contraction = IdentifyContraction(std::span(&d.ramp, 1)).contraction;
    est.irc = IdentifyIrc(IrcMethod::kRampCorrelation, d.ramp).irc;
    TrialColumns sparse = d.sparse, dense = d.dense;
    for (auto* tr : {&sparse, &dense}) {
      if (gcv) {
        const auto fit = GcvSmoothingSpline(tr->t_s, tr->angle_deg);
        tr->velocity_deg_s = fit.first;
        tr->accel_deg_s2 = fit.second;
      }
      tr->activation =
          ActivationAt(est.contraction, est.irc, tr == &sparse ? d.sparse_pulses : d.dense_pulses,
                       kDefaultPulseRateHz, tr->t_s);
    }
    est.passive =
        IdentifyPassiveFreeSwing(std::span(&sparse, 1), d.truth.passive.torque_angle).passive;
    est.active = IdentifyActive(std::span(&dense, 1), est.passive).active;
    benchmark::DoNotOptimize(est);
  }
}
BENCHMARK(BM_RapidChain)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// What a clinician waits for after a rapid run: IdentifyRapid (§7.4.1) on
// the ramp and the two swings as the bench records them (no velocity: the
// GCV splines derive it), with its output-error refinement (6
// Levenberg–Marquardt iterations, the default).
void BM_IdentifyRapidRefined(benchmark::State& state) {
  const Data& d = GetData();
  TrialColumns iso;
  iso.t_s = d.ramp.t_s;
  iso.stim_ma = d.ramp.stim_ma;
  iso.torque_nm = d.ramp.torque_nm;
  std::vector<TrialColumns> swings(2);
  for (std::size_t k = 0; k < 2; ++k) {
    const TrialColumns& src = k == 0 ? d.sparse : d.dense;
    swings[k].t_s = src.t_s;
    swings[k].stim_ma = src.stim_ma;
    swings[k].angle_deg = src.angle_deg;
  }
  RapidOptions o;
  o.inertia_kgm2 = d.truth.passive.inertia_kgm2;
  for (auto _ : state) benchmark::DoNotOptimize(IdentifyRapid(iso, swings, o));
}
BENCHMARK(BM_IdentifyRapidRefined)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace fesbench::model
