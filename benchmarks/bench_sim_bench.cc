// Speed of the simulated bench (docs/ARCHITECTURE.md, "The benches"): bench time per wall time for
// the rapid protocol's control loop — 30 s of bench time at 1 kHz control
// (a set-point and AdvanceTo every 1 ms, sensors read at 200 Hz) must take
// well under 1 s. The counter `bench_s_per_wall_s` is the speed-up over
// real time.

#include <cmath>

#include <benchmark/benchmark.h>

#include "model/units.h"
#include "server/bench/simulated_bench.h"
#include "server/bench/virtual_subject.h"

namespace {

using fesbench::server::DrawVirtualSubject;
using fesbench::server::MotorMode;
using fesbench::server::SimulatedBench;
using fesbench::server::SimulatedBenchOptions;

// mode 0: free swing under a stimulation train; 1: position servo with
// stimulation; 2: locked (isometric) with stimulation.
void BM_SimulatedBench30s(benchmark::State& state) {
  const int mode = static_cast<int>(state.range(0));
  const auto subject = DrawVirtualSubject(17);  // default (full) fidelity
  constexpr int kSteps = 30'000;
  for (auto _ : state) {
    SimulatedBenchOptions o;
    o.initial_angle_deg = 80.0;
    o.initial_mode = mode == 0 ? MotorMode::kDecoupled
                               : (mode == 1 ? MotorMode::kPosition : MotorMode::kLocked);
    const std::unique_ptr<SimulatedBench> bench_owner = SimulatedBench::Create(subject, o).value();
    SimulatedBench& bench = *bench_owner;
    double sum = 0.0;
    for (int k = 0; k < kSteps; ++k) {
      const double t = k * 1e-3;
      if (k % 5 == 0) {
        bench.SetStimAmplitude((k / 1000) % 3 == 0 ? subject.max_tolerated_ma * 0.8 : 0.0);
        sum += bench.ReadSensors().angle_deg;
      }
      if (mode == 1) {
        bench.SetMotorSetpoint(60.0 + 30.0 * std::sin(2.0 * fesbench::model::kPi * 0.3 * t));
      }
      bench.AdvanceTo(t + 1e-3);
    }
    benchmark::DoNotOptimize(sum);
    benchmark::DoNotOptimize(bench.DrainEmg_mv());
  }
  state.counters["bench_s_per_wall_s"] = benchmark::Counter(
      30.0 * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SimulatedBench30s)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
