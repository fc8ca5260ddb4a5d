#include "model/quality.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace fesbench::model {
namespace {

TEST(CompareEmg, FlagsAVoluntaryContraction) {
  std::mt19937 rng(9);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<double> relaxed(100), relaxed2(100), contracted(100);
  for (int i = 0; i < 100; ++i) {
    relaxed[static_cast<std::size_t>(i)] = 0.02 * n(rng) + 1.0;  // offset is removed
    relaxed2[static_cast<std::size_t>(i)] = 0.02 * n(rng) - 3.0;
    contracted[static_cast<std::size_t>(i)] = 0.2 * n(rng);
  }
  const EmgComparison same = CompareEmg(relaxed, relaxed2);
  EXPECT_FALSE(same.voluntary_contraction);
  EXPECT_NEAR(same.ratio, 1.0, 0.3);
  const EmgComparison up = CompareEmg(relaxed, contracted);
  EXPECT_TRUE(up.voluntary_contraction);
  EXPECT_NEAR(up.ratio, 10.0, 3.0);
  EXPECT_TRUE(CompareEmg(contracted, relaxed).voluntary_contraction);  // relaxed only after
  EXPECT_THROW(CompareEmg(relaxed, relaxed, 1.0), std::invalid_argument);
  EXPECT_THROW(CompareEmg(std::vector<double>{1.0}, relaxed), std::invalid_argument);
}

TEST(CompareEmgPrePost, UsesFirstAndLastTenthOfASecond) {
  std::vector<double> emg(1000, 0.0);
  for (std::size_t i = 0; i < emg.size(); ++i)
    emg[i] = (i % 2 ? 1.0 : -1.0) * (i >= 900 ? 3.0 : 1.0);
  const EmgComparison c = CompareEmgPrePost(emg, 1000.0);
  EXPECT_NEAR(c.pre_rms, 1.0, 1e-12);
  EXPECT_NEAR(c.post_rms, 3.0, 1e-12);
  EXPECT_TRUE(c.voluntary_contraction);
  EXPECT_THROW(CompareEmgPrePost(std::vector<double>(150, 0.0), 1000.0), std::invalid_argument);
}

TEST(PhasePlaneCoverage, CountsVisitedCells) {
  const std::vector<double> ae = {0, 10, 20}, ve = {-1, 0, 1};
  const std::vector<double> a = {5, 5, 15, 25}, v = {-0.5, -0.2, 0.5, 0.0};  // last outside
  const Coverage c = PhasePlaneCoverage(a, v, ae, ve);
  EXPECT_EQ(c.cells_total, 4);
  EXPECT_EQ(c.cells_visited, 2);
  EXPECT_DOUBLE_EQ(c.share, 0.5);
  EXPECT_EQ(c.counts[0], 2);  // (0–10, −1–0)
  EXPECT_EQ(c.counts[3], 1);  // (10–20, 0–1)
  EXPECT_EQ(PhasePlaneCoverage(a, v, ae, ve, 2).cells_visited, 1);
  EXPECT_FALSE(CoverageWarning("x", c, 0.75).empty());
  EXPECT_TRUE(CoverageWarning("x", c, 0.5).empty());
  EXPECT_THROW(PhasePlaneCoverage(a, v, std::vector<double>{0}, ve), std::invalid_argument);
}

}  // namespace
}  // namespace fesbench::model
