#include "model/piecewise_linear.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace fesbench::model {

PiecewiseLinear::PiecewiseLinear(std::vector<double> x, std::vector<double> y)
    : x_(std::move(x)), y_(std::move(y)) {
  if (x_.empty()) throw std::invalid_argument("piecewise-linear curve: no breakpoints");
  if (x_.size() != y_.size()) {
    throw std::invalid_argument("piecewise-linear curve: wrong argument size: expected " +
                                std::to_string(x_.size()) + " ordinates, got " +
                                std::to_string(y_.size()));
  }
  for (std::size_t i = 0; i < x_.size(); ++i) {
    if (!std::isfinite(x_[i]) || !std::isfinite(y_[i])) {
      throw std::invalid_argument("piecewise-linear curve: non-finite value at index " +
                                  std::to_string(i));
    }
    if (i > 0 && !(x_[i] > x_[i - 1])) {
      throw std::invalid_argument(
          "piecewise-linear curve: breakpoints not strictly increasing at index " +
          std::to_string(i));
    }
  }
}

PiecewiseLinear PiecewiseLinear::Constant(double value, double at) {
  return PiecewiseLinear({at}, {value});
}

PiecewiseLinear PiecewiseLinear::Uniform(double x_min, double x_max, std::vector<double> y) {
  if (y.size() < 2) throw std::invalid_argument("Uniform: need at least 2 ordinates");
  if (!(x_min < x_max)) throw std::invalid_argument("Uniform: x_min must be below x_max");
  std::vector<double> x(y.size());
  const double dx = (x_max - x_min) / static_cast<double>(y.size() - 1);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = x_min + dx * static_cast<double>(i);
  x.back() = x_max;
  return PiecewiseLinear(std::move(x), std::move(y));
}

BasisWeights PiecewiseLinear::Basis(std::span<const double> bp, double x) {
  const std::size_t m = bp.size();
  if (m == 1 || x <= bp.front()) return {0, 1.0, 0.0};
  if (x >= bp.back()) return {m - 2, 0.0, 1.0};
  // First breakpoint strictly greater than x; x lies in (bp[hi-1], bp[hi]].
  const auto it = std::upper_bound(bp.begin(), bp.end(), x);
  const std::size_t hi = static_cast<std::size_t>(it - bp.begin());
  const std::size_t lo = hi - 1;
  const double w_hi = (x - bp[lo]) / (bp[hi] - bp[lo]);  // Eq. 4.30
  return {lo, 1.0 - w_hi, w_hi};
}

BasisWeights PiecewiseLinear::Basis(std::span<const double> bp, double x, std::size_t& segment) {
  const std::size_t m = bp.size();
  if (m == 1 || x <= bp.front()) return {0, 1.0, 0.0};
  if (x >= bp.back()) return {m - 2, 0.0, 1.0};
  // bp[lo] <= x < bp[lo + 1], the segment the binary search finds.
  std::size_t lo = std::min(segment, m - 2);
  while (x < bp[lo]) --lo;
  while (x >= bp[lo + 1]) ++lo;
  segment = lo;
  const double w_hi = (x - bp[lo]) / (bp[lo + 1] - bp[lo]);  // Eq. 4.30
  return {lo, 1.0 - w_hi, w_hi};
}

double PiecewiseLinear::operator()(double x) const {
  const BasisWeights b = Basis(x_, x);
  if (b.weight_hi == 0.0) return y_[b.index_lo];
  return b.weight_lo * y_[b.index_lo] + b.weight_hi * y_[b.index_lo + 1];
}

double PiecewiseLinear::operator()(double x, std::size_t& segment) const {
  const BasisWeights b = Basis(x_, x, segment);
  if (b.weight_hi == 0.0) return y_[b.index_lo];
  return b.weight_lo * y_[b.index_lo] + b.weight_hi * y_[b.index_lo + 1];
}

double PiecewiseLinear::Slope(double x) const {
  if (x_.size() < 2 || x < x_.front() || x >= x_.back()) return 0.0;
  const auto it = std::upper_bound(x_.begin(), x_.end(), x);
  const std::size_t hi = static_cast<std::size_t>(it - x_.begin());
  return (y_[hi] - y_[hi - 1]) / (x_[hi] - x_[hi - 1]);
}

PiecewiseLinear PiecewiseLinear::Shifted(double dy) const {
  std::vector<double> y = y_;
  for (double& v : y) v += dy;
  return PiecewiseLinear(x_, std::move(y));
}

PiecewiseLinear PiecewiseLinear::Scaled(double k) const {
  std::vector<double> y = y_;
  for (double& v : y) v *= k;
  return PiecewiseLinear(x_, std::move(y));
}

PiecewiseLinear PiecewiseLinear::Resampled(std::vector<double> x) const {
  std::vector<double> y(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) y[i] = (*this)(x[i]);
  return PiecewiseLinear(std::move(x), std::move(y));
}

}  // namespace fesbench::model
