#pragma once

/// @file
/// Linear least squares by truncated singular value decomposition
/// (Eqs. 4.14–4.26, §4.2.2) and the piecewise-linear design columns of
/// Eq. 4.30 used by the passive and active fits.

#include <Eigen/Dense>
#include <cstddef>
#include <span>
#include <string>
#include <vector>

namespace fesbench::model {

/// The solution of min |A·c − b|² (Eq. 4.18).
struct LeastSquaresSolution {
  Eigen::VectorXd c;                ///< parameters (Eq. 4.24).
  int rank = 0;                     ///< singular values kept.
  double rms = 0.0;                 ///< sqrt(mean residual²), in b's unit.
  Eigen::VectorXd singular_values;  ///< of the column-scaled A, descending (see below).
};

/// Solves min |A·c − b|² by SVD with small singular values zeroed
/// (Eqs. 4.19–4.26): c = V·p, p_j = g_j / w_j for w_j > tol·w_max, else 0,
/// which is the shortest solution when A is rank deficient (e.g. a
/// breakpoint the data never visit, or the constant shared by τ_pta and
/// τ_ptv, §6.5). Columns are scaled to unit norm first; A is reduced by a
/// Householder QR and the SVD is taken of the small R factor, whose singular
/// values equal those of A, so the cost is that of the QR. When A's
/// spectrum separates clearly (every singular value either ≥ 0.01·w_max or
/// in a subspace A maps below 1e-2·relative_tolerance·w_max, as a fit's
/// structural null directions), the QR and the SVD are replaced by the
/// eigendecomposition of AᵀA: the same rank, the solution within ~1e-10
/// relative, the truncated singular values given as upper bounds.
/// @param relative_tolerance singular values below this times the largest
///   are zeroed (Eq. 4.26); > 0.
/// @throws std::invalid_argument if A has no rows or columns, b's size
///   differs from A's rows, or relative_tolerance <= 0.
LeastSquaresSolution SolveTruncatedSvd(const Eigen::MatrixXd& a, const Eigen::VectorXd& b,
                                       double relative_tolerance = 1e-10);
/// The same, scaling and factorising `a` in place (no copy of the design
/// matrix): for a caller with no further use for it.
LeastSquaresSolution SolveTruncatedSvd(Eigen::MatrixXd&& a, const Eigen::VectorXd& b,
                                       double relative_tolerance = 1e-10);

/// A least-squares problem min |A·c − b|² held as an equivalent one with
/// fewer rows: |A·c − b|² = |a·c − this b|² + outside_sq for every c (a and
/// this b are Qᵀ·A's and Qᵀ·b's leading rows for an orthogonal Q, outside_sq
/// the square of the rest of Qᵀ·b), A having `rows` rows.
struct ReducedLeastSquares {
  Eigen::MatrixXd a;
  Eigen::VectorXd b;
  double outside_sq = 0.0;
  Eigen::Index rows = 0;
};

/// SolveTruncatedSvd of the problem a reduced one stands for: the same
/// solution (Qᵀ·A has A's column norms, so the same scaling, and A's
/// singular values), rank and singular values; rms over A's rows.
/// @throws std::invalid_argument as SolveTruncatedSvd.
LeastSquaresSolution SolveTruncatedSvd(ReducedLeastSquares&& problem,
                                       double relative_tolerance = 1e-10);

/// The rows of a design of piecewise-linear curves (Eq. 4.30) — the basis
/// of one curve's breakpoints, optionally a second's, then `dense` columns
/// of values per row — with `rhs` right-hand sides, to be handed to
/// SolveTruncatedSvd reduced. A row's basis entries are (1 − w, w) at its
/// segment's two breakpoints, so the rows that share a cell (a segment of
/// each curve) are Z·U, Z's rows (1, w₁, w₂, the dense values) and U fixed
/// by the cell: a Householder QR of each cell's [Z | b] leaves R_Z·U (at
/// most 3 + dense rows per cell) with Q_Zᵀb, and what is left of b goes
/// into outside_sq. A trial's samples visit a few dozen cells of the phase
/// plane, so the fit's QR is taken of a few hundred rows, not of the N
/// samples (O(N·(3 + dense)²) for the cells instead of O(N·M²)).
class PwlLeastSquares {
 public:
  /// Columns: bp_first.size() basis columns, bp_second.size() (none if it
  /// is empty), then `dense`; breakpoints strictly increasing (not
  /// checked), bp_first non-empty. Room is made for `expected_rows` rows.
  /// @throws std::invalid_argument if bp_first is empty or dense or rhs is
  ///   negative.
  PwlLeastSquares(std::span<const double> bp_first, std::span<const double> bp_second, int dense,
                  int rhs, std::size_t expected_rows = 0);

  /// Adds the row of abscissae x_first, x_second (ignored without a second
  /// curve), `dense` values and right-hand sides (sizes as constructed; not
  /// checked). The basis is found from the last row's segments
  /// (PiecewiseLinear::Basis with a hint).
  void AddRow(double x_first, double x_second, std::span<const double> dense,
              std::span<const double> rhs);

  /// Rows added.
  Eigen::Index rows() const { return static_cast<Eigen::Index>(cell_.size()); }
  /// Columns of A.
  Eigen::Index cols() const;

  /// The reduced problem of right-hand side `rhs`, with `extra_rows` zero
  /// rows below for the caller to fill (counted in `rows`).
  ReducedLeastSquares Reduced(int rhs, Eigen::Index extra_rows = 0) const;

  /// |A·c − b|² of right-hand side `rhs` over the rows added.
  double ResidualSquared(const Eigen::VectorXd& c, int rhs) const;

 private:
  std::vector<double> bp_first_, bp_second_;
  std::size_t cells_ = 1, segments_second_ = 1;
  int dense_ = 0, rhs_ = 0;
  int k_ = 0;                      // columns of Z: 1, w₁, [w₂,] dense
  int width_ = 0;                  // k_ + rhs_: a stored row
  std::vector<double> z_;          // the rows of [Z | b], row-major
  std::vector<std::size_t> cell_;  // each row's cell
  std::size_t hint_first_ = 0, hint_second_ = 0;
};

/// Solves min |A·c − b|² subject to c ≥ 0 by the active-set method of
/// Lawson and Hanson (Solving Least Squares Problems, 1974, ch. 23): columns
/// are freed one at a time by the largest gradient component, each free set
/// solved by SolveTruncatedSvd, and a step that would turn a free
/// coefficient negative is cut back to the boundary. Used where an ordinate
/// is a gain, which a muscle cannot make negative (§3.4).
/// @throws std::invalid_argument as SolveTruncatedSvd.
Eigen::VectorXd SolveNonNegative(const Eigen::MatrixXd& a, const Eigen::VectorXd& b);

/// Writes the Eq. 4.30 basis of breakpoints `bp` at abscissa x, times
/// `scale`, into row `row`, columns col0 .. col0 + bp.size() − 1, of `a`
/// (which must be large enough; not checked).
void SetPwlBasisRow(Eigen::MatrixXd& a, Eigen::Index row, Eigen::Index col0,
                    std::span<const double> bp, double x, double scale = 1.0);

/// Sum over samples of each breakpoint's basis weight (Eq. 4.30): how much
/// data supports each ordinate. A breakpoint with support near 0 is not
/// determined by the data.
std::vector<double> BreakpointSupport(std::span<const double> bp, std::span<const double> x);

/// Warnings for breakpoints whose support is below `min_support` samples,
/// naming the curve, e.g. "tau_ptv: breakpoint 350 deg/s has support 0.2
/// samples (under-determined)".
std::vector<std::string> SupportWarnings(const std::string& curve, const std::string& unit,
                                         std::span<const double> bp,
                                         std::span<const double> support, double min_support);

}  // namespace fesbench::model
