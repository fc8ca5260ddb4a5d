// Paging at scale on both engines (docs/ARCHITECTURE.md, storage): the first page and a deep page
// (the last full one) of GET /parameter-sets?limit=50 and GET
// /subjects?limit=50, as the routes ask the repositories (one row more than
// the page, to know a next page exists), over 1k, 10k, 100k and — with
// FESBENCH_BENCH_1M=1 — 1M rows. Target: p50 at 100k ≤ 2 × p50 at 1k.
//
// SQLite: a file in the system temp directory. PostgreSQL: a server of its
// own started like the tests' (tests/support: initdb in a temporary folder,
// fsync off — it measures reads). Rows are made in bulk with SQL (a subject
// with revision 1 and a right leg, and one parameter set per subject whose
// params_json is a real set's JSON), then ANALYZE as a live database would
// have had.
//
//   build/benchmarks/paging_bench --benchmark_repetitions=3 --benchmark_report_aggregates_only=true

#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "api/parameter_set_json.h"
#include "model/parameter_set.h"
#include "storage/database.h"
#include "storage/parameter_sets.h"
#include "storage/subjects.h"
#include "tests/support/postgres_server.h"

namespace fesbench::storage {
namespace {

namespace fs = std::filesystem;

fesbench::testing::PostgresServer* Postgres() {
  static std::unique_ptr<fesbench::testing::PostgresServer> server = [] {
    auto started = fesbench::testing::PostgresServer::Start(
        fs::temp_directory_path() / ("fesbench_paging_pg_" + std::to_string(::getpid())));
    if (!started.ok()) throw std::runtime_error(started.status().ToString());
    return std::move(*started);
  }();
  return server.get();
}

// The bulk fill of `rows` subjects, legs, revisions and parameter sets.
api::Status Fill(Database& db, std::int64_t rows) {
  const std::string json = api::ParameterSetToJson(model::ExampleParameterSet()).dump();
  const bool pg = db.engine() == Engine::kPostgres;
  const std::string series = pg ? "FROM generate_series(1, ?1) AS n(i)" : "FROM n";
  const std::string with =
      pg ? "" : "WITH RECURSIVE n(i) AS (SELECT 1 UNION ALL SELECT i + 1 FROM n WHERE i < ?1) ";
  const std::string at = "'2026-01-01T00:00:00.000000Z'";
  const std::string statements[] = {
      with + "INSERT INTO subjects (id, code, created_at_utc) SELECT i, 'P' || i, " + at + " " +
          series,
      with + "INSERT INTO subject_revisions (id, subject_id, revision, sex, recorded_at_utc)"
             " SELECT i, i, 1, 'undisclosed', " + at + " " + series,
      with + "INSERT INTO legs (id, subject_id, side, created_at_utc) SELECT i, i, 'right', " +
          at + " " + series,
      with + "INSERT INTO parameter_sets (id, subject_id, leg_id, version, model, irc_method,"
             " passive_method, active_method, created_at_utc, params_json)"
             " SELECT i, i, i, 1, 'full', 'ramp_correlation', 'free_swing', 'log_least_squares', " +
          at + ", ?2 " + series,
  };
  for (const std::string& sql : statements) {
    api::Status status = db.Write([&](Connection& c) -> api::Status {
      auto s = c.Prepare(sql);
      if (!s.ok()) return s.status();
      s->Bind(1, rows);
      if (sql.find("?2") != std::string::npos) s->Bind(2, json);
      return s->Run();
    });
    if (!status.ok()) return status;
  }
  if (pg) {  // identity columns continue after the rows made here
    for (const char* table : {"subjects", "subject_revisions", "legs", "parameter_sets"}) {
      auto status = db.Write([&](Connection& c) {
        return c.QueryText(std::string("SELECT setval(pg_get_serial_sequence('") + table +
                           "', 'id'), " + std::to_string(rows) + ")")
            .status();
      });
      if (!status.ok()) return status;
    }
  }
  return api::Status::Ok();
}

struct Filled {
  fs::path dir;
  std::string database_name;
  std::unique_ptr<Database> db;
};

Database& DatabaseWith(bool postgres, std::int64_t rows) {
  static std::map<std::pair<bool, std::int64_t>, std::unique_ptr<Filled>> cache;
  auto& slot = cache[{postgres, rows}];
  if (slot) return *slot->db;
  slot = std::make_unique<Filled>();
  DatabaseOptions options;
  options.bench_id = "bench";
  if (postgres) {
    fesbench::testing::PostgresServer* server = Postgres();
    slot->database_name = "paging_" + std::to_string(rows);
    const std::string base = server->Url("");
    if (auto s = fesbench::testing::CreateDatabase(base, slot->database_name); !s.ok()) {
      throw std::runtime_error(s.ToString());
    }
    options.path = server->Url(slot->database_name);
  } else {
    slot->dir = fs::temp_directory_path() /
                ("fesbench_paging_" + std::to_string(::getpid()) + "_" + std::to_string(rows));
    fs::remove_all(slot->dir);
    fs::create_directories(slot->dir);
    options.path = (slot->dir / "paging.db").string();
  }
  auto opened = Database::Open(options);
  if (!opened.ok()) throw std::runtime_error(opened.status().ToString());
  slot->db = std::move(*opened);
  if (auto s = Fill(*slot->db, rows); !s.ok()) throw std::runtime_error(s.ToString());
  // The statistics a live database has (autovacuum / ANALYZE).
  if (auto s = slot->db->Write([](Connection& c) { return c.ExecScript("ANALYZE"); }); !s.ok()) {
    throw std::runtime_error(s.ToString());
  }
  return *slot->db;
}

// range(0): 0 SQLite, 1 PostgreSQL; range(1): 0 parameter sets, 1 subjects;
// range(2): rows; range(3): 0 first page, 1 the deepest full page.
void BM_ListPage(benchmark::State& state) {
  const bool postgres = state.range(0) == 1;
  const bool subjects = state.range(1) == 1;
  const std::int64_t rows = state.range(2);
  const bool deep = state.range(3) == 1;
  Database* db = nullptr;
  try {
    db = &DatabaseWith(postgres, rows);
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  const std::int64_t after = deep ? rows - 51 : 0;
  for (auto _ : state) {
    std::size_t got = 0;
    if (subjects) {
      auto page = SubjectRepository(*db).ListPage(after, 51);
      got = page.ok() ? page->size() : 0;
    } else {
      ParameterSetListQuery q;
      q.after_id = after;
      q.limit = 51;
      auto page = ParameterSetRepository(*db).List(q);
      got = page.ok() ? page->size() : 0;
    }
    if (got < 50) state.SkipWithError("short page");
    benchmark::DoNotOptimize(got);
  }
  state.SetLabel(std::string(postgres ? "postgresql " : "sqlite ") +
                 (subjects ? "subjects " : "parameter-sets ") + (deep ? "deep page" : "first page"));
}

void Sizes(benchmark::internal::Benchmark* b) {
  std::vector<std::int64_t> sizes = {1000, 10000, 100000};
  if (const char* big = std::getenv("FESBENCH_BENCH_1M"); big != nullptr && *big == '1') {
    sizes.push_back(1000000);
  }
  for (int engine : {0, 1}) {
    for (int list : {0, 1}) {
      for (std::int64_t rows : sizes) {
        for (int deep : {0, 1}) b->Args({engine, list, rows, deep});
      }
    }
  }
}
BENCHMARK(BM_ListPage)->Apply(Sizes)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace fesbench::storage
