#pragma once

/// @file
/// One-dimensional minimisation by a coarse grid scan followed by
/// golden-section refinement around the best grid point (used for the GCV
/// smoothing parameter and the twitch pole).

#include <cmath>
#include <limits>
#include <stdexcept>

namespace fesbench::model {

/// A point of a one-dimensional search and the cost there.
struct ScalarMinimum {
  double x = 0.0;
  double cost = 0.0;
};

/// The two candidates of GridGoldenSearch: the best grid point and where the
/// golden-section refinement ended. Callers pick (the refinement can end
/// above the grid's best when the cost is not unimodal in the bracket).
struct GridGoldenResult {
  ScalarMinimum grid;
  ScalarMinimum golden;
};

/// Evaluates `cost(x)` at lo + i·h, i = 0 … grid_steps (h = (hi − lo) /
/// grid_steps), then runs `iterations` golden-section steps on
/// [best − h, best + h]. `cost` is called in a fixed order (grid points
/// ascending, then the two interior points, then one per step).
/// @throws std::invalid_argument if grid_steps < 1, iterations < 0 or
///   !(lo < hi).
template <typename Cost>
GridGoldenResult GridGoldenSearch(Cost&& cost, double lo, double hi, int grid_steps,
                                  int iterations) {
  if (grid_steps < 1 || iterations < 0 || !(lo < hi)) {
    throw std::invalid_argument("GridGoldenSearch: need grid_steps >= 1, iterations >= 0, lo < hi");
  }
  const double step = (hi - lo) / grid_steps;
  ScalarMinimum grid{lo, std::numeric_limits<double>::infinity()};
  for (int i = 0; i <= grid_steps; ++i) {
    const double x = lo + step * i;
    const double f = cost(x);
    if (f < grid.cost) grid = {x, f};
  }
  double a = grid.x - step, b = grid.x + step;
  const double r = (std::sqrt(5.0) - 1.0) / 2.0;
  double c = b - r * (b - a), d = a + r * (b - a);
  double fc = cost(c), fd = cost(d);
  for (int it = 0; it < iterations; ++it) {
    if (fc < fd) {
      b = d, d = c, fd = fc;
      c = b - r * (b - a);
      fc = cost(c);
    } else {
      a = c, c = d, fc = fd;
      d = a + r * (b - a);
      fd = cost(d);
    }
  }
  return {grid, fc < fd ? ScalarMinimum{c, fc} : ScalarMinimum{d, fd}};
}

}  // namespace fesbench::model
