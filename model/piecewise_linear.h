#pragma once

/// @file
/// Piecewise-linear curves (thesis §3.4) and their least-squares basis
/// functions (Eqs. 4.27–4.30, §4.2.2).

#include <cstddef>
#include <span>
#include <vector>

namespace fesbench::model {

/// The two non-zero basis functions of Eq. 4.30 at one abscissa: the value of
/// a piecewise-linear curve with ordinates c is
/// `weight_lo * c[index_lo] + weight_hi * c[index_lo + 1]`.
/// Outside the breakpoints the curve holds its end value, so there
/// `weight_lo == 1` (left end) or `weight_hi == 1` (right end).
struct BasisWeights {
  std::size_t index_lo = 0;
  double weight_lo = 1.0;
  double weight_hi = 0.0;
};

/// A curve y(x) through breakpoints (x̃_j, c_j), j = 1..M, linear between
/// them (Eq. 4.27) and constant beyond the first and last breakpoint.
/// Immutable once built; cheap to copy for the small M the model uses.
class PiecewiseLinear {
 public:
  /// An empty curve; it cannot be evaluated (check `empty()`).
  PiecewiseLinear() = default;

  /// @param x breakpoints x̃_j, strictly increasing, finite.
  /// @param y ordinates c_j, finite, same length as x.
  /// @throws std::invalid_argument if x is empty, the sizes differ, x is not
  ///   strictly increasing, or any value is NaN or infinite.
  PiecewiseLinear(std::vector<double> x, std::vector<double> y);

  /// A constant curve y(x) = value (one breakpoint at x = at).
  static PiecewiseLinear Constant(double value, double at = 0.0);

  /// Breakpoints evenly spaced over [x_min, x_max] with ordinates y.
  /// @throws std::invalid_argument if y has fewer than 2 values or
  ///   x_min >= x_max.
  static PiecewiseLinear Uniform(double x_min, double x_max, std::vector<double> y);

  /// y(x): linear interpolation, end values held outside (Eq. 4.27).
  double operator()(double x) const;

  /// dy/dx at x (the slope of the segment containing x; 0 outside the
  /// breakpoints). At a breakpoint, the slope of the segment to its right.
  double Slope(double x) const;

  /// Basis weights of Eq. 4.30 at x for these breakpoints.
  BasisWeights Basis(double x) const { return Basis(x_, x); }

  /// Basis weights of Eq. 4.30 at x for arbitrary breakpoints (strictly
  /// increasing, non-empty; not checked).
  static BasisWeights Basis(std::span<const double> breakpoints, double x);

  /// The same weights, the segment found by a scan from `segment` (0 at
  /// first, then the index_lo of the last look-up, which it receives)
  /// instead of a binary search: along a sweep through nearby abscissae
  /// (a trial's samples) the scan rarely takes a step.
  static BasisWeights Basis(std::span<const double> breakpoints, double x, std::size_t& segment);

  /// y(x) as operator(), the segment scanned from `segment` as in Basis.
  double operator()(double x, std::size_t& segment) const;

  /// The same breakpoints with every ordinate plus dy.
  PiecewiseLinear Shifted(double dy) const;
  /// The same breakpoints with every ordinate times k.
  PiecewiseLinear Scaled(double k) const;
  /// The curve resampled at new breakpoints (strictly increasing).
  PiecewiseLinear Resampled(std::vector<double> x) const;

  const std::vector<double>& x() const { return x_; }
  const std::vector<double>& y() const { return y_; }
  std::size_t size() const { return x_.size(); }
  bool empty() const { return x_.empty(); }

  friend bool operator==(const PiecewiseLinear&, const PiecewiseLinear&) = default;

 private:
  std::vector<double> x_;
  std::vector<double> y_;
};

}  // namespace fesbench::model
