// Speed of the model's forward simulation (simulate.h): one 10 s free-swing
// prediction of ExampleParameterSet() under a seeded random-binary pulse
// train, RK4 with a 1 ms internal step, 200 Hz output. Target: < 1 ms per
// prediction on one core (identification and the web client's predictions
// call this in loops).

#include <benchmark/benchmark.h>

#include <random>

#include "model/contraction.h"
#include "model/joint_model.h"
#include "model/parameter_set.h"
#include "model/signal.h"
#include "model/simulate.h"

namespace fesbench::model {
namespace {

// 0.25 s slots on (40 mA) or off, 200 Hz envelope, 33 Hz pulses; seeded.
PulseTrain RandomBinaryTrain(double duration_s, unsigned seed) {
  std::mt19937 rng(seed);
  std::bernoulli_distribution on(0.5);
  SampledSignal env;
  env.rate_hz = 200.0;
  const int n = static_cast<int>(duration_s * env.rate_hz);
  while (static_cast<int>(env.values.size()) < n) {
    const double v = on(rng) ? 40.0 : 0.0;
    for (int k = 0; k < 50 && static_cast<int>(env.values.size()) < n; ++k) env.values.push_back(v);
  }
  return PulsesFromEnvelope(env, kDefaultPulseRateHz);
}

void BM_FreeSwing10sRk4(benchmark::State& state) {
  const ParameterSet params = ExampleParameterSet();
  const PulseTrain pulses = RandomBinaryTrain(10.0, 42u);
  SimulationOptions options;
  options.integrator = IntegratorKind::kRk4;
  options.step_s = 1e-3;
  options.output_rate_hz = 200.0;
  options.duration_s = 10.0;
  for (auto _ : state) {
    SimulationResult r = SimulateFreeSwing(params, pulses, options);
    benchmark::DoNotOptimize(r.angle_deg.data());
  }
  state.counters["pulses"] = static_cast<double>(pulses.size());
}
BENCHMARK(BM_FreeSwing10sRk4)->Unit(benchmark::kMicrosecond);

void BM_FreeSwing10sAdaptive(benchmark::State& state) {
  const ParameterSet params = ExampleParameterSet();
  const PulseTrain pulses = RandomBinaryTrain(10.0, 42u);
  SimulationOptions options;
  options.integrator = IntegratorKind::kAdaptive;
  options.duration_s = 10.0;
  for (auto _ : state) {
    SimulationResult r = SimulateFreeSwing(params, pulses, options);
    benchmark::DoNotOptimize(r.angle_deg.data());
  }
}
BENCHMARK(BM_FreeSwing10sAdaptive)->Unit(benchmark::kMicrosecond);

void BM_Isometric10s(benchmark::State& state) {
  const ParameterSet params = ExampleParameterSet();
  const PulseTrain pulses = RandomBinaryTrain(10.0, 42u);
  SimulationOptions options;
  options.duration_s = 10.0;
  for (auto _ : state) {
    SimulationResult r = SimulateIsometric(params, pulses, 90.0, options);
    benchmark::DoNotOptimize(r.torque_nm.data());
  }
}
BENCHMARK(BM_Isometric10s)->Unit(benchmark::kMicrosecond);

// One evaluation of the equation of motion's right-hand side.
void BM_JointModelAcceleration(benchmark::State& state) {
  const JointModel model = JointModel::FromParameters(ExampleParameterSet());
  double angle = 20.0;
  for (auto _ : state) {
    angle = angle > 100.0 ? 20.0 : angle + 0.37;
    benchmark::DoNotOptimize(model.AccelerationDegS2(angle, 3.0 * angle - 150.0, 0.4));
  }
}
BENCHMARK(BM_JointModelAcceleration);

}  // namespace
}  // namespace fesbench::model
