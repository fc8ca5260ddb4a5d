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
/// values equal those of A, so the cost is that of the QR. When R's
/// spectrum separates clearly (every singular value either ≥ 0.01·w_max or
/// in a subspace R maps below 1e-2·relative_tolerance·w_max, as a fit's
/// structural null directions), the SVD is replaced by the
/// eigendecomposition of RᵀR: the same rank, the solution within ~1e-10
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

/// The design matrix [X(θ) | X(θ̇) | 0] of an angle curve and a velocity
/// curve fitted together (Eq. 4.30 basis, as in Eqs. 4.31 and 4.40): row i
/// holds the basis of `bp_angle` at angle_deg[i] in columns 0 … ma − 1 and
/// of `bp_velocity` at velocity_deg_s[i] in columns ma … ma + mv − 1,
/// followed by `extra_columns` zero columns for the caller to fill.
/// @throws std::invalid_argument if angle_deg and velocity_deg_s differ in
///   size or extra_columns < 0.
Eigen::MatrixXd AngleVelocityDesign(std::span<const double> bp_angle,
                                    std::span<const double> angle_deg,
                                    std::span<const double> bp_velocity,
                                    std::span<const double> velocity_deg_s,
                                    Eigen::Index extra_columns);

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
