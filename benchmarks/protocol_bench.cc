// The protocol engine on the simulated bench as fast as possible (time
// scale 0): the whole rapid_parameterisation (≈ 29.5 s of bench time:
// ramp IRC, free-swing passive and active random-binary trials, then the
// §7.4.1 identification). Counters: bench_s (bench seconds per run) and
// bench_per_wall (bench seconds per wall second).
#include <benchmark/benchmark.h>

#include <chrono>

#include "server/bench/simulated_bench.h"
#include "server/protocols/plan.h"
#include "server/protocols/runner.h"

namespace {

using namespace fesbench::server;
using namespace fesbench::server::protocols;

void BM_RapidParameterisation(benchmark::State& state) {
  const VirtualSubject vs = DrawVirtualSubject(7);
  SubjectContext ctx;
  ctx.threshold_ma = vs.threshold_ma;
  ctx.max_tolerated_ma = vs.max_tolerated_ma;
  ctx.min_angle_deg = 15.0;
  ctx.max_angle_deg = 108.0;
  ctx.inertia_kgm2 = vs.truth.passive.inertia_kgm2;
  auto plan = MakePlan("rapid_parameterisation", {}, ctx);
  if (!plan.ok()) {
    state.SkipWithError(plan.status().ToString().c_str());
    return;
  }
  double bench_s = 0.0, wall_s = 0.0;
  for (auto _ : state) {
    const std::unique_ptr<SimulatedBench> bench_owner =
        SimulatedBench::Create(vs).value();  // time_scale 0: as fast as possible
    SimulatedBench& bench = *bench_owner;
    SafetyEventLog log;
    SafeBench safe(bench, log.sink());
    RunnerOptions o;
    o.arm_watchdog = false;
    ProtocolRunner runner(safe, &log, nullptr, o);
    const auto t0 = std::chrono::steady_clock::now();
    const RunResult r = runner.Run(*plan, ctx);
    wall_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    bench_s += r.bench_duration_s;
    if (r.state != RunState::kDone) {
      state.SkipWithError(r.reason.c_str());
      return;
    }
    benchmark::DoNotOptimize(r.parameter_set);
  }
  state.counters["bench_s"] = bench_s / static_cast<double>(state.iterations());
  state.counters["bench_per_wall"] = bench_s / wall_s;
}
BENCHMARK(BM_RapidParameterisation)->Unit(benchmark::kMillisecond);

// The engine alone (recording, offsets, progress) over the rapid plan on a
// bench that only keeps time: the runner's own cost per 1 ms tick.
class ClockBench final : public Bench {
 public:
  std::string_view kind() const override { return "clock"; }
  const BenchLimits& limits() const override { return limits_; }
  void SetStimAmplitude(double) override {}
  void TriggerPulse(double) override {}
  void RestartPulseClock() override {}
  std::vector<fesbench::model::Pulse> DrainDeliveredPulses() override { return {}; }
  void SetMotorMode(MotorMode) override {}
  void SetMotorSetpoint(double) override {}
  double Now_s() const override { return t_; }
  void AdvanceTo(double t_s) override { t_ = t_s; }
  SensorFrame ReadSensors() override { return {t_, 90.0, 0.0, 0.0, 0.0, false, false, false}; }
  std::vector<double> DrainEmg_mv() override { return {}; }
  void HardwareEStop() override {}
  void ClearHardwareEStop() override {}
  bool HardwareEStopped() const override { return false; }

 private:
  BenchLimits limits_;
  double t_ = 0.0;
};

void BM_EngineTicksOnly(benchmark::State& state) {
  SubjectContext ctx;
  auto plan = MakePlan("prediction_random_binary", {}, ctx);
  std::int64_t ticks = 0;
  for (auto _ : state) {
    ClockBench bench;
    SafeBench safe(bench, {});
    RunnerOptions o;
    o.arm_watchdog = false;
    ProtocolRunner runner(safe, nullptr, nullptr, o);
    const RunResult r = runner.Run(*plan, ctx);
    if (r.state != RunState::kDone) {
      state.SkipWithError(r.reason.c_str());
      return;
    }
    benchmark::DoNotOptimize(r.trials);
    ticks += plan->total_ticks();
  }
  state.counters["ticks_per_s"] =
      benchmark::Counter(static_cast<double>(ticks), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_EngineTicksOnly)->Unit(benchmark::kMillisecond);

}  // namespace
