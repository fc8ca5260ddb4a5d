// Storage benchmarks (issue targets: insert a 10 s trial under 2 ms; a
// subject's parameter-set history among 10,000 stored sets under 2 ms).
// Databases live in the system temp directory on the local disk.
//
//   build/benchmarks/storage_bench --benchmark_repetitions=5

#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <numbers>
#include <string>

#include "storage/database.h"
#include "storage/parameter_sets.h"
#include "storage/sessions.h"
#include "storage/subjects.h"
#include "storage/trials.h"

namespace fesbench::storage {
namespace {

struct BenchDb {
  std::filesystem::path dir;
  std::unique_ptr<Database> db;
  std::int64_t session_id = 0;
  std::vector<std::int64_t> subject_ids;

  explicit BenchDb(const std::string& tag, Synchronous synchronous) {
    dir = std::filesystem::temp_directory_path() /
          ("fesbench_bench_" + tag + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    DatabaseOptions options;
    options.path = (dir / "bench.db").string();
    options.synchronous = synchronous;
    auto opened = Database::Open(options);
    if (!opened.ok()) throw std::runtime_error(opened.status().ToString());
    db = std::move(*opened);
  }
  ~BenchDb() {
    db.reset();
    std::filesystem::remove_all(dir);
  }

  // A subject with a right leg and one session; returns {subject, leg, session}.
  std::array<std::int64_t, 3> AddSubject(const std::string& code) {
    SubjectRepository subjects(*db);
    auto subject = subjects.Create(code, SubjectDetails{});
    auto leg = subjects.AddLeg(subject->id, Side::kRight);
    auto session =
        SessionRepository(*db).Create(subject->id, leg->id, {"2026-01-02", "shank", {}, {}, ""});
    return {subject->id, leg->id, session->id};
  }
};

// 10 s at 200 Hz: 2,000 samples × 6 channels (t_s and five signals).
api::Trial TenSecondTrial() {
  api::Trial trial;
  trial.name = "bench";
  constexpr std::size_t kSamples = 2000;
  std::vector<double> t(kSamples), a(kSamples), v(kSamples), tau(kSamples), acc(kSamples),
      u(kSamples);
  for (std::size_t i = 0; i < kSamples; ++i) {
    t[i] = static_cast<double>(i) / 200.0;
    a[i] = 60 + 30 * std::sin(2 * std::numbers::pi * t[i]);
    v[i] = 60 * std::numbers::pi * std::cos(2 * std::numbers::pi * t[i]);
    tau[i] = 5 * std::sin(3 * t[i]);
    acc[i] = 9.81 * std::cos(t[i]);
    u[i] = 20 + static_cast<double>(i % 33);
  }
  trial.SetChannel("t_s", t);
  trial.SetChannel("angle_deg", a);
  trial.SetChannel("velocity_deg_s", v);
  trial.SetChannel("torque_nm", tau);
  trial.SetChannel("accel_m_s2", acc);
  trial.SetChannel("stim_ma", u);
  return trial;
}

Synchronous SyncOf(const benchmark::State& state) {
  return state.range(0) == 0 ? Synchronous::kFull : Synchronous::kNormal;
}

void BM_InsertTrial10s(benchmark::State& state) {
  BenchDb bench("insert", SyncOf(state));
  const auto ids = bench.AddSubject("B1");
  TrialRepository trials(*bench.db);
  const api::Trial trial = TenSecondTrial();
  for (auto _ : state) {
    auto id = trials.Insert({ids[2], std::nullopt}, trial);
    if (!id.ok()) state.SkipWithError(id.status().ToString().c_str());
    benchmark::DoNotOptimize(id);
  }
  state.SetLabel(state.range(0) == 0 ? "synchronous=FULL" : "synchronous=NORMAL");
}
BENCHMARK(BM_InsertTrial10s)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

void BM_ReadTrial10s(benchmark::State& state) {
  BenchDb bench("read", Synchronous::kFull);
  const auto ids = bench.AddSubject("B1");
  TrialRepository trials(*bench.db);
  auto id = trials.Insert({ids[2], std::nullopt}, TenSecondTrial());
  for (auto _ : state) {
    auto trial = trials.Get(*id);
    if (!trial.ok() || trial->channels.size() != 6) state.SkipWithError("read failed");
    benchmark::DoNotOptimize(trial);
  }
}
BENCHMARK(BM_ReadTrial10s)->Unit(benchmark::kMicrosecond);

void BM_InsertAndReadTrial10s(benchmark::State& state) {
  BenchDb bench("roundtrip", SyncOf(state));
  const auto ids = bench.AddSubject("B1");
  TrialRepository trials(*bench.db);
  const api::Trial trial = TenSecondTrial();
  for (auto _ : state) {
    auto id = trials.Insert({ids[2], std::nullopt}, trial);
    auto back = trials.Get(*id);
    if (!back.ok() || back->channels[5].values.size() != 2000) state.SkipWithError("failed");
    benchmark::DoNotOptimize(back);
  }
  state.SetLabel(state.range(0) == 0 ? "synchronous=FULL" : "synchronous=NORMAL");
}
BENCHMARK(BM_InsertAndReadTrial10s)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// 10,000 sets: 100 subjects × 100 versions, one per day; the query returns
// one subject's 100 versions (or a 30-day window of them).
BenchDb& HistoryDb() {
  static BenchDb* bench = [] {
    auto* b = new BenchDb("history", Synchronous::kFull);
    const api::UtcTime start =
        std::chrono::sys_days{std::chrono::year{2025} / 1 / 1} + std::chrono::microseconds(0);
    auto status = b->db->Write([&](Connection&) -> api::Status {
      ParameterSetRepository sets(*b->db);
      model::ParameterSet params = model::ExampleParameterSet();
      params.provenance.irc_method = "ramp_correlation";
      params.provenance.passive_method = "free_swing";
      for (int s = 0; s < 100; ++s) {
        const auto ids = b->AddSubject("H" + std::to_string(s));
        b->subject_ids.push_back(ids[0]);
        for (int v = 0; v < 100; ++v) {
          params.contraction.pole_per_s = 20.0 + 0.01 * v;
          auto r = sets.Insert({ids[0], ids[1], params, std::nullopt,
                                start + std::chrono::days(v) + std::chrono::seconds(s)});
          if (!r.ok()) return r.status();
        }
      }
      return api::Status::Ok();
    });
    if (!status.ok()) throw std::runtime_error(status.ToString());
    return b;
  }();
  return *bench;
}

void BM_HistoryQuery(benchmark::State& state) {
  BenchDb& bench = HistoryDb();
  ParameterSetRepository sets(*bench.db);
  const std::int64_t subject = bench.subject_ids[57];
  for (auto _ : state) {
    auto history = sets.History({subject, std::nullopt, std::nullopt, std::nullopt, std::nullopt});
    if (!history.ok() || history->size() != 100) state.SkipWithError("history failed");
    benchmark::DoNotOptimize(history);
  }
  state.SetLabel("100 of 10000 sets");
}
BENCHMARK(BM_HistoryQuery)->Unit(benchmark::kMicrosecond);

void BM_HistoryQueryDateRangeAndMethod(benchmark::State& state) {
  BenchDb& bench = HistoryDb();
  ParameterSetRepository sets(*bench.db);
  const std::int64_t subject = bench.subject_ids[57];
  const api::UtcTime from =
      std::chrono::sys_days{std::chrono::year{2025} / 2 / 1} + std::chrono::microseconds(0);
  for (auto _ : state) {
    auto history = sets.History(
        {subject, std::nullopt, std::string("free_swing"), from, from + std::chrono::days(30)});
    if (!history.ok() || history->size() != 30) state.SkipWithError("history failed");
    benchmark::DoNotOptimize(history);
  }
  state.SetLabel("30 of 10000 sets");
}
BENCHMARK(BM_HistoryQueryDateRangeAndMethod)->Unit(benchmark::kMicrosecond);

// GET /parameter-sets?limit=50 (the list's keyset page, one row more to
// know a next page exists): the first page, and the last page after
// 9,950 sets; range(0) = 1 filters by one subject.
void BM_ParameterSetListPage(benchmark::State& state) {
  BenchDb& bench = HistoryDb();
  ParameterSetRepository sets(*bench.db);
  ParameterSetListQuery q;
  q.limit = 51;
  if (state.range(0) == 1) q.subject_id = bench.subject_ids[57];
  if (state.range(1) == 1) {
    ParameterSetListQuery all;
    all.subject_id = q.subject_id;
    all.limit = 100000;
    auto every = sets.List(all);
    if (!every.ok() || every->size() < 51) {
      state.SkipWithError("list failed");
      return;
    }
    q.after_id = (*every)[every->size() - 51].id;  // the deepest full page
  }
  for (auto _ : state) {
    auto page = sets.List(q);
    if (!page.ok() || page->size() < 50) state.SkipWithError("page failed");
    benchmark::DoNotOptimize(page);
  }
  state.SetLabel(std::string(state.range(0) == 1 ? "one subject's " : "all ") +
                 (state.range(1) == 1 ? "deepest page" : "first page") + " of 10000 sets");
}
BENCHMARK(BM_ParameterSetListPage)
    ->Args({0, 0})
    ->Args({0, 1})
    ->Args({1, 0})
    ->Args({1, 1})
    ->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace fesbench::storage
