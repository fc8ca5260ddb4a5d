#include "model/piecewise_linear.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace fesbench::model {
namespace {

TEST(PiecewiseLinear, InterpolatesLinearlyAndHoldsEndValues) {
  const PiecewiseLinear f({0.0, 10.0, 30.0}, {1.0, 3.0, -1.0});
  EXPECT_DOUBLE_EQ(f(0.0), 1.0);
  EXPECT_DOUBLE_EQ(f(5.0), 2.0);
  EXPECT_DOUBLE_EQ(f(10.0), 3.0);
  EXPECT_DOUBLE_EQ(f(20.0), 1.0);
  EXPECT_DOUBLE_EQ(f(-100.0), 1.0);
  EXPECT_DOUBLE_EQ(f(100.0), -1.0);
  EXPECT_DOUBLE_EQ(f.Slope(5.0), 0.2);
  EXPECT_DOUBLE_EQ(f.Slope(25.0), -0.2);
  EXPECT_DOUBLE_EQ(f.Slope(-1.0), 0.0);
  EXPECT_DOUBLE_EQ(f.Slope(30.0), 0.0);
}

TEST(PiecewiseLinear, BasisReproducesTheCurveAndSumsToOne) {
  // Eq. 4.29: y(x) = Σ c_j X_j(x) with X_j of Eq. 4.30.
  const PiecewiseLinear f({-2.0, 0.5, 1.0, 4.0}, {3.0, -1.0, 2.0, 5.0});
  for (double x = -3.0; x <= 5.0; x += 0.137) {
    const BasisWeights b = f.Basis(x);
    EXPECT_NEAR(b.weight_lo + b.weight_hi, 1.0, 1e-15);
    EXPECT_GE(b.weight_lo, 0.0);
    EXPECT_GE(b.weight_hi, 0.0);
    const double y = b.weight_lo * f.y()[b.index_lo] +
                     (b.weight_hi != 0.0 ? b.weight_hi * f.y()[b.index_lo + 1] : 0.0);
    EXPECT_NEAR(y, f(x), 1e-12) << "x = " << x;
  }
}

// The segment-hinted look-ups give exactly the binary search's weights and
// values, whatever segment the scan starts from.
TEST(PiecewiseLinear, HintedLookUpEqualsTheBinarySearch) {
  const PiecewiseLinear f({-2.0, 0.5, 1.0, 4.0, 4.5}, {3.0, -1.0, 2.0, 5.0, 0.25});
  std::size_t sweep = 0;
  for (double x = -3.0; x <= 5.0; x += 0.0137) {
    for (std::size_t start = 0; start < 6; ++start) {
      std::size_t segment = start;
      const BasisWeights h = PiecewiseLinear::Basis(f.x(), x, segment);
      const BasisWeights b = f.Basis(x);
      EXPECT_EQ(h.index_lo, b.index_lo) << "x = " << x;
      EXPECT_EQ(h.weight_lo, b.weight_lo) << "x = " << x;
      EXPECT_EQ(h.weight_hi, b.weight_hi) << "x = " << x;
      segment = start;
      EXPECT_EQ(f(x, segment), f(x)) << "x = " << x;
    }
    EXPECT_EQ(f(x, sweep), f(x)) << "x = " << x;
    EXPECT_EQ(f(-x, sweep), f(-x)) << "x = " << -x;
  }
  std::size_t segment = 3;
  EXPECT_EQ(PiecewiseLinear::Constant(2.0)(7.0, segment), 2.0);
}

TEST(PiecewiseLinear, ConstantAndUniform) {
  const PiecewiseLinear c = PiecewiseLinear::Constant(2.5);
  EXPECT_DOUBLE_EQ(c(-1e6), 2.5);
  EXPECT_DOUBLE_EQ(c(1e6), 2.5);
  const PiecewiseLinear u = PiecewiseLinear::Uniform(10.0, 110.0, {0, 1, 2, 3, 4, 5});
  EXPECT_EQ(u.size(), 6u);
  EXPECT_DOUBLE_EQ(u.x()[1], 30.0);
  EXPECT_DOUBLE_EQ(u(40.0), 1.5);
}

TEST(PiecewiseLinear, ShiftScaleResample) {
  const PiecewiseLinear f({0.0, 1.0}, {1.0, 3.0});
  EXPECT_DOUBLE_EQ(f.Shifted(2.0)(0.5), 4.0);
  EXPECT_DOUBLE_EQ(f.Scaled(-2.0)(0.5), -4.0);
  const PiecewiseLinear r = f.Resampled({0.0, 0.25, 1.0});
  EXPECT_DOUBLE_EQ(r.y()[1], 1.5);
}

TEST(PiecewiseLinear, RejectsInvalidBreakpoints) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(PiecewiseLinear({}, {}), std::invalid_argument);
  EXPECT_THROW(PiecewiseLinear({0.0, 1.0}, {1.0}), std::invalid_argument);
  EXPECT_THROW(PiecewiseLinear({0.0, 0.0}, {1.0, 2.0}), std::invalid_argument);
  EXPECT_THROW(PiecewiseLinear({1.0, 0.0}, {1.0, 2.0}), std::invalid_argument);
  EXPECT_THROW(PiecewiseLinear({0.0, nan}, {1.0, 2.0}), std::invalid_argument);
  EXPECT_THROW(PiecewiseLinear({0.0, 1.0}, {1.0, INFINITY}), std::invalid_argument);
}

}  // namespace
}  // namespace fesbench::model
