// Integration: `fesbench study` (issue 10) with 2 virtual legs against a real
// fesbench-server on loopback (--time-scale 0, no DDS): the tables' files and
// structure, the inertia truth column against the seeded generator, t-test
// df = n − 1, and determinism (two servers, same seeds → identical CSVs).

#include "clients/cli/study/study.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "clients/cli/api_client.h"
#include "server/bench/virtual_subject.h"
#include "server_process.h"

namespace fesbench::testing {
namespace {

namespace fs = std::filesystem;

std::string ReadAll(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::vector<std::vector<std::string>> ReadCsv(const fs::path& path) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::string cell;
    bool quoted = false;
    for (char c : line) {
      if (c == '"') {
        quoted = !quoted;
      } else if (c == ',' && !quoted) {
        cells.push_back(cell);
        cell.clear();
      } else {
        cell += c;
      }
    }
    cells.push_back(cell);
    rows.push_back(cells);
  }
  return rows;
}

const std::vector<std::string> kCsvs = {"table_6_1_isometric_irc",
                                        "table_6_2_isometric_order",
                                        "table_6_3_inertia",
                                        "table_6_4_linearised",
                                        "table_6_5_6_8_ttests",
                                        "table_6_9_simplified",
                                        "appendix_jk_per_leg_errors",
                                        "mean_errors",
                                        "median_errors",
                                        "bench_time"};

fs::path RunTwoLegStudy(const std::string& name, bool plots) {
  ServerProcess server({"--seed", "5"});
  cli::ApiClient client(
      cli::CliConfig{"http://127.0.0.1:" + std::to_string(server.port()), server.admin_token()});
  cli::study::StudyOptions options;
  options.legs = 2;
  options.seed = 3;
  options.plots = plots;
  options.output_dir =
      fs::temp_directory_path() / ("fesbench-study-" + name + "-" + std::to_string(::getpid()));
  fs::remove_all(options.output_dir);
  std::ostringstream log;
  const cli::study::StudySummary summary = cli::study::RunStudy(client, options, log);
  EXPECT_EQ(summary.legs_done, 2) << log.str();
  EXPECT_EQ(server.Terminate(), 0);
  return options.output_dir;
}

TEST(StudyTest, TwoLegStudyWritesTablesAndIsDeterministic) {
  const fs::path a = RunTwoLegStudy("a", true);
  for (const auto& name : kCsvs) ASSERT_TRUE(fs::exists(a / (name + ".csv"))) << name;
  ASSERT_TRUE(fs::exists(a / "study.md"));
  ASSERT_TRUE(fs::exists(a / "plots.gp"));
  ASSERT_TRUE(fs::exists(a / "plot_rb1.dat"));
  EXPECT_NE(ReadAll(a / "study.md").find("Table 6.3"), std::string::npos);

  // Table 6.3: header, 2 legs + mean + sd; truth = the seeded draws.
  const auto inertia = ReadCsv(a / "table_6_3_inertia.csv");
  ASSERT_EQ(inertia.size(), 1u + 2u + 2u);
  ASSERT_EQ(inertia[0].back(), "truth");
  for (int leg = 1; leg <= 2; ++leg) {
    const auto truth = server::DrawVirtualSubject(3 * 1000 + static_cast<std::uint64_t>(leg));
    EXPECT_NEAR(std::stod(inertia[static_cast<std::size_t>(leg)].back()),
                truth.truth.passive.inertia_kgm2, 1e-4);
    // The anthropometric (column 1) and simultaneous (column 2) inertias
    // are near the truth (the free-swing fit is not: see docs/STUDY.md).
    for (std::size_t c : {1u, 2u}) {
      const std::string& cell = inertia[static_cast<std::size_t>(leg)][c];
      if (cell == "n/a") continue;
      EXPECT_GT(std::stod(cell), 0.5 * truth.truth.passive.inertia_kgm2) << inertia[0][c];
      EXPECT_LT(std::stod(cell), 2.0 * truth.truth.passive.inertia_kgm2) << inertia[0][c];
    }
  }

  // t-tests: df = n − 1 wherever computed; n ≤ 2; at least one computed.
  int computed = 0;
  for (const std::string name :
       {"table_6_1_isometric_irc", "table_6_5_6_8_ttests", "table_6_9_simplified"}) {
    const auto rows = ReadCsv(a / (name + ".csv"));
    ASSERT_GE(rows.size(), 2u) << name;
    ASSERT_EQ(rows[0][9], "df");
    for (std::size_t r = 1; r < rows.size(); ++r) {
      ASSERT_EQ(rows[r].size(), rows[0].size());
      const int n = std::stoi(rows[r][3]);
      EXPECT_LE(n, 2);
      if (rows[r][9] == "n/a") continue;
      EXPECT_DOUBLE_EQ(std::stod(rows[r][9]), n - 1.0) << name << " row " << r;
      ++computed;
    }
  }
  EXPECT_GT(computed, 10);

  // Per-leg errors: every E_RMS computed is ≥ 0 and at least E_ABS (RMS ≥
  // mean absolute value; the isometric Eq. 6.1 / 6.2 rows have no E_ABS).
  const auto errors = ReadCsv(a / "appendix_jk_per_leg_errors.csv");
  ASSERT_GT(errors.size(), 50u);
  for (std::size_t r = 1; r < errors.size(); ++r) {
    if (errors[r][3] == "n/a") continue;
    EXPECT_GE(std::stod(errors[r][3]), 0.0);
    if (errors[r][4] == "n/a") continue;
    EXPECT_GE(std::stod(errors[r][3]) + 1e-4, std::stod(errors[r][4]));
  }

  // Bench time: rapid < traditional (§7.4.1).
  const auto bench = ReadCsv(a / "bench_time.csv");
  ASSERT_EQ(bench.size(), 4u);
  EXPECT_LT(std::stod(bench[3][1]), std::stod(bench[3][2]));

  // Determinism: a second fresh server with the same seeds.
  const fs::path b = RunTwoLegStudy("b", false);
  for (const auto& name : kCsvs) {
    EXPECT_EQ(ReadAll(a / (name + ".csv")), ReadAll(b / (name + ".csv"))) << name;
  }
  fs::remove_all(a);
  fs::remove_all(b);
}

}  // namespace
}  // namespace fesbench::testing
