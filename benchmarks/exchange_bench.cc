// Data in and out (docs/API.md, "Session archives"): reading a 30 s recording from CSV with unit
// conversions, laying a bench-like trial out as BIDS files and reading it
// back, and packing those files as zip and tar.gz.

#include <benchmark/benchmark.h>

#include <cmath>
#include <string>

#include "api/bids.h"
#include "api/trial_import.h"
#include "server/services/session_archive.h"

namespace fesbench {
namespace {

constexpr int kSamples = 6000;  // 30 s at 200 Hz

// A 30 s, 200 Hz recording as another rig writes it: ms, rad, A, N·mm.
std::string RigCsv() {
  std::string csv = "Time (ms),Knee (rad),I (A),Torque (N.mm)\n";
  for (int i = 0; i < kSamples; ++i) {
    csv += std::to_string(i * 5) + "," + std::to_string(1.4 + 0.3 * std::sin(i / 50.0)) + "," +
           (i % 400 < 200 ? "0.03" : "0") + "," + std::to_string(1000.0 * std::cos(i / 30.0)) +
           "\n";
  }
  return csv;
}

api::Trial BenchTrial() {
  api::Trial t;
  t.id = 7;
  t.name = "prediction_random_binary";
  std::vector<double> time, angle, torque, stim, accel, delivered;
  for (int i = 0; i < kSamples; ++i) {
    time.push_back(i / 200.0);
    angle.push_back(90.0 + 25.0 * std::sin(i / 37.0));
    torque.push_back(0.4 * std::cos(i / 11.0));
    stim.push_back(i % 400 < 200 ? 31.5 : 0.0);
    accel.push_back(3.0 * std::sin(i / 5.0));
    delivered.push_back(stim.back());
  }
  t.SetChannel("t_s", time);
  t.SetChannel("stim_ma", stim);
  t.SetChannel("angle_deg", angle);
  t.SetChannel("torque_nm", torque);
  t.SetChannel("accel_m_s2", accel);
  t.SetChannel("stim_delivered_ma", delivered);
  api::ChannelGroup emg;
  emg.sample_rate_hz = 1000.0;
  std::vector<double> et, ev;
  for (int i = 0; i < kSamples * 5; ++i) {
    et.push_back(i / 1000.0);
    ev.push_back(0.02 * std::sin(i * 1.7));
  }
  emg.Set("t_s", et);
  emg.Set("emg_mv", ev);
  t.emg = emg;
  api::PulseRecord pulses;
  for (int k = 0; k < 990; ++k) pulses.Append(k / 33.0, k % 12 < 6 ? 31.5 : 0.0);
  t.pulses = pulses;
  return t;
}

void BM_ImportCsv30s(benchmark::State& state) {
  const std::string csv = RigCsv();
  api::ImportSpec spec;
  spec.kind = "prediction_step";
  spec.time_column = "Time (ms)";
  spec.time_unit = "ms";
  spec.columns = {{"Knee (rad)", "angle_deg", "rad"},
                  {"I (A)", "stim_ma", "A"},
                  {"Torque (N.mm)", "torque_nm", "N.mm"}};
  for (auto _ : state) {
    auto trial = api::ImportTrialText(csv, spec);
    if (!trial.ok()) state.SkipWithError(trial.status().message().c_str());
    benchmark::DoNotOptimize(trial);
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * csv.size()));
}
BENCHMARK(BM_ImportCsv30s)->Unit(benchmark::kMillisecond);

void BM_BidsTrialRoundTrip30s(benchmark::State& state) {
  const api::Trial trial = BenchTrial();
  for (auto _ : state) {
    api::FileMap files;
    api::AddBidsTrial(trial, {"S01", "1", "right", 7}, files);
    auto back = api::ReadBidsTrials(files);
    if (!back.ok()) state.SkipWithError(back.status().message().c_str());
    benchmark::DoNotOptimize(back);
  }
}
BENCHMARK(BM_BidsTrialRoundTrip30s)->Unit(benchmark::kMillisecond);

void BM_PackArchive30s(benchmark::State& state) {
  api::FileMap files;
  api::AddBidsTrial(BenchTrial(), {"S01", "1", "right", 7}, files);
  std::size_t raw = 0;
  for (const auto& [path, content] : files) raw += content.size();
  const auto format = state.range(0) == 0 ? server::services::ArchiveFormat::kZip
                                          : server::services::ArchiveFormat::kTarGz;
  std::size_t packed = 0;
  for (auto _ : state) {
    auto archive = server::services::PackArchive(files, format, "s");
    packed = archive.ok() ? archive->size() : 0;
    benchmark::DoNotOptimize(archive);
  }
  state.counters["raw_MB"] = static_cast<double>(raw) / 1e6;
  state.counters["packed_MB"] = static_cast<double>(packed) / 1e6;
  state.SetLabel(state.range(0) == 0 ? "zip" : "tar.gz");
}
BENCHMARK(BM_PackArchive30s)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace fesbench
