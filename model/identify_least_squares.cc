#include "model/identify_least_squares.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <stdexcept>
#include <utility>
#include <vector>

#include "model/piecewise_linear.h"

namespace fesbench::model {

namespace {

// Checks the arguments of SolveTruncatedSvd and returns the column
// scaling: basis weights (0–1) and accelerations (~10² rad/s²) share one
// matrix; equilibrating keeps the truncation scale-free.
Eigen::VectorXd ColumnScale(const Eigen::MatrixXd& a, const Eigen::VectorXd& b,
                            double relative_tolerance) {
  if (a.rows() == 0 || a.cols() == 0) {
    throw std::invalid_argument("SolveTruncatedSvd: empty design matrix");
  }
  if (b.size() != a.rows()) {
    throw std::invalid_argument("SolveTruncatedSvd: wrong argument size: expected " +
                                std::to_string(a.rows()) + " observations, got " +
                                std::to_string(b.size()));
  }
  if (!(relative_tolerance > 0.0)) {
    throw std::invalid_argument("SolveTruncatedSvd: relative_tolerance must be positive");
  }
  Eigen::VectorXd scale(a.cols());
  for (Eigen::Index j = 0; j < a.cols(); ++j) {
    const double n = a.col(j).norm();
    scale(j) = n > 0.0 ? 1.0 / n : 1.0;
  }
  return scale;
}

// Eqs. 4.19–4.26 through the eigendecomposition AᵀA = V·diag(λ)·Vᵀ instead
// of the SVD (a sixth of the Jacobi SVD's time at M = 23, and no QR: with
// A = Q·R, AᵀA = RᵀR, |A·v| = |R·v| and Aᵀb = Rᵀ·(Qᵀb)): A's singular
// values are w_j = √λ_j, its right singular vectors V's columns, and
// g_j/w_j = u_jᵀ·b/w_j = v_jᵀ·Aᵀb/λ_j, so the truncated solution is
// c = Σ_kept v_j·(v_jᵀ·Aᵀb)/λ_j. Forming AᵀA squares the conditioning: λ_j
// is resolved only to ~M·ε·λ_max, which cannot tell a singular value of
// 1e-9·w_max (kept) from a structural zero. So this answers only when the
// spectrum separates clearly (else returns false and the SVD decides):
//   - every λ_j ≥ kKeptShare·λ_max, each then relative to ~M·ε/kKeptShare
//     (≈ 5e-11 at M = 23), kept, well above the truncation;
//   - the rest span a subspace S on which |A·V_S|_F is below the
//     truncation w_j ≤ tolerance·w_max by the factor kMargin: by
//     Courant–Fischer the SVD's |S| smallest singular values are at most
//     |A·V_S|₂ ≤ |A·V_S|_F, so the SVD zeroes the same directions.
// The computed V_S is off the true subspace by ~ε·λ_max/gap; a gap too
// small to make |A·V_S| that small falls back too.
bool SolveByGram(const Eigen::MatrixXd& a, const Eigen::VectorXd& b, double relative_tolerance,
                 Eigen::VectorXd& c_scaled, int& rank, Eigen::VectorXd& w) {
  constexpr double kKeptShare = 1e-4;  // λ_j/λ_max, i.e. w_j ≥ 0.01·w_max
  constexpr double kMargin = 1e-2;
  const Eigen::Index m = a.cols();
  if (a.rows() < m || !(relative_tolerance < kMargin * std::sqrt(kKeptShare))) return false;
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(m, m);
  gram.selfadjointView<Eigen::Lower>().rankUpdate(a.transpose());
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(gram);  // λ ascending
  if (eig.info() != Eigen::Success) return false;
  const Eigen::VectorXd& lambda = eig.eigenvalues();
  const double lambda_max = lambda(m - 1);
  if (!(lambda_max > 0.0)) return false;
  Eigen::Index small = 0;  // λ_0 … λ_{small−1} form S
  while (small < m && lambda(small) < kKeptShare * lambda_max) ++small;
  const double w_max = std::sqrt(lambda_max);
  const auto v_small = eig.eigenvectors().leftCols(small);
  const Eigen::MatrixXd a_small = a * v_small;
  if (!(a_small.norm() <= kMargin * relative_tolerance * w_max)) return false;
  const auto v_kept = eig.eigenvectors().rightCols(m - small);
  const Eigen::VectorXd proj = v_kept.transpose() * (a.transpose() * b);
  c_scaled = v_kept * proj.cwiseQuotient(lambda.tail(m - small));
  rank = static_cast<int>(m - small);
  // Descending, as JacobiSVD's: the kept √λ, then the bounds |A·v_j|.
  w.resize(m);
  for (Eigen::Index j = 0; j < m - small; ++j) w(j) = std::sqrt(lambda(m - 1 - j));
  for (Eigen::Index j = 0; j < small; ++j) w(m - 1 - j) = a_small.col(j).norm();
  std::sort(w.data() + (m - small), w.data() + m, std::greater<>());
  return true;
}

// SolveTruncatedSvd on the column-scaled matrix `a` (overwritten), of a
// problem whose residual has `outside_sq` beyond a's rows and `rows` rows
// in all (ReducedLeastSquares; a's own otherwise).
LeastSquaresSolution SolveScaled(Eigen::MatrixXd& a, const Eigen::VectorXd& scale,
                                 const Eigen::VectorXd& b, double relative_tolerance,
                                 double outside_sq, Eigen::Index rows) {
  LeastSquaresSolution out;
  Eigen::VectorXd c_scaled, w;
  if (SolveByGram(a, b, relative_tolerance, c_scaled, out.rank, w)) {
    outside_sq += (a * c_scaled - b).squaredNorm();
  } else {
    // A = Q·R; the singular values of A equal those of R (M×M), so the
    // SVD of Eq. 4.19 is taken of R and g = U_Rᵀ·(Qᵀ·b) (Eq. 4.23). The
    // QR overwrites the scaled matrix.
    const Eigen::Index m = a.cols();
    Eigen::MatrixXd r;
    Eigen::VectorXd qtb;
    if (a.rows() >= m) {
      Eigen::HouseholderQR<Eigen::Ref<Eigen::MatrixXd>> qr(a);
      r = qr.matrixQR().topRows(m).triangularView<Eigen::Upper>();
      const Eigen::VectorXd full = qr.householderQ().transpose() * b;
      qtb = full.head(m);
      // |b|² outside the column space: the rows of Qᵀ·b below M.
      outside_sq += full.tail(a.rows() - m).squaredNorm();
    } else {
      r = a;
      qtb = b;
    }
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(r, Eigen::ComputeThinU | Eigen::ComputeThinV);
    w = svd.singularValues();
    const Eigen::VectorXd g = svd.matrixU().transpose() * qtb;
    Eigen::VectorXd p = Eigen::VectorXd::Zero(w.size());
    const double w_max = w.size() > 0 ? w(0) : 0.0;
    for (Eigen::Index j = 0; j < w.size(); ++j) {
      if (w(j) > relative_tolerance * w_max) {  // Eqs. 4.25–4.26
        p(j) = g(j) / w(j);
        ++out.rank;
      }
    }
    c_scaled = svd.matrixV() * p;
    // |A·c − b|² = |R·c_scaled − (Qᵀ·b)_head|² + |(Qᵀ·b)_tail|² (Q
    // orthogonal): no pass over the N rows again.
    outside_sq += (r * c_scaled - qtb).squaredNorm();
  }
  out.c = scale.asDiagonal() * c_scaled;  // Eq. 4.24, unscaled
  out.rms = std::sqrt(outside_sq / static_cast<double>(rows));
  out.singular_values = w;
  return out;
}

}  // namespace

LeastSquaresSolution SolveTruncatedSvd(const Eigen::MatrixXd& a, const Eigen::VectorXd& b,
                                       double relative_tolerance) {
  const Eigen::VectorXd scale = ColumnScale(a, b, relative_tolerance);
  Eigen::MatrixXd as = a * scale.asDiagonal();
  return SolveScaled(as, scale, b, relative_tolerance, 0.0, a.rows());
}

LeastSquaresSolution SolveTruncatedSvd(Eigen::MatrixXd&& a, const Eigen::VectorXd& b,
                                       double relative_tolerance) {
  const Eigen::VectorXd scale = ColumnScale(a, b, relative_tolerance);
  for (Eigen::Index j = 0; j < a.cols(); ++j) a.col(j) *= scale(j);
  return SolveScaled(a, scale, b, relative_tolerance, 0.0, a.rows());
}

LeastSquaresSolution SolveTruncatedSvd(ReducedLeastSquares&& problem, double relative_tolerance) {
  Eigen::MatrixXd& a = problem.a;
  const Eigen::VectorXd scale = ColumnScale(a, problem.b, relative_tolerance);
  for (Eigen::Index j = 0; j < a.cols(); ++j) a.col(j) *= scale(j);
  return SolveScaled(a, scale, problem.b, relative_tolerance, problem.outside_sq, problem.rows);
}

PwlLeastSquares::PwlLeastSquares(std::span<const double> bp_first,
                                 std::span<const double> bp_second, int dense, int rhs,
                                 std::size_t expected_rows)
    : bp_first_(bp_first.begin(), bp_first.end()),
      bp_second_(bp_second.begin(), bp_second.end()),
      dense_(dense),
      rhs_(rhs) {
  if (bp_first_.empty() || dense < 0 || rhs < 0) {
    throw std::invalid_argument("PwlLeastSquares: no breakpoints, or dense or rhs negative");
  }
  const auto segments = [](const std::vector<double>& bp) {
    return bp.size() > 1 ? bp.size() - 1 : std::size_t{1};
  };
  segments_second_ = segments(bp_second_);
  cells_ = segments(bp_first_) * segments_second_;
  k_ = (bp_second_.empty() ? 2 : 3) + dense;
  width_ = k_ + rhs;
  z_.reserve(expected_rows * static_cast<std::size_t>(width_));
  cell_.reserve(expected_rows);
}

Eigen::Index PwlLeastSquares::cols() const {
  return static_cast<Eigen::Index>(bp_first_.size() + bp_second_.size()) + dense_;
}

void PwlLeastSquares::AddRow(double x_first, double x_second, std::span<const double> dense,
                             std::span<const double> rhs) {
  const BasisWeights b1 = PiecewiseLinear::Basis(bp_first_, x_first, hint_first_);
  std::size_t cell = b1.index_lo * segments_second_;
  z_.push_back(1.0);
  z_.push_back(b1.weight_hi);
  if (!bp_second_.empty()) {
    const BasisWeights b2 = PiecewiseLinear::Basis(bp_second_, x_second, hint_second_);
    cell += b2.index_lo;
    z_.push_back(b2.weight_hi);
  }
  z_.insert(z_.end(), dense.begin(), dense.end());
  z_.insert(z_.end(), rhs.begin(), rhs.end());
  cell_.push_back(cell);
}

ReducedLeastSquares PwlLeastSquares::Reduced(int rhs, Eigen::Index extra_rows) const {
  // The rows of [Z | b_rhs] grouped by cell (a counting sort).
  const std::size_t n = cell_.size(), w = static_cast<std::size_t>(k_) + 1;
  std::vector<std::size_t> start(cells_ + 1, 0);
  for (const std::size_t c : cell_) ++start[c + 1];
  for (std::size_t c = 0; c < cells_; ++c) start[c + 1] += start[c];
  std::vector<double> block(n * w);
  {
    std::vector<std::size_t> next(start.begin(), start.end() - 1);
    const auto stride = static_cast<std::size_t>(width_);
    for (std::size_t i = 0; i < n; ++i) {
      double* to = block.data() + next[cell_[i]]++ * w;
      const double* from = z_.data() + i * stride;
      std::copy(from, from + k_, to);
      to[k_] = from[k_ + rhs];
    }
  }
  // Each cell's Householder QR in place: R_Z and Q_Zᵀb in its first rows,
  // Q_Zᵀb's rest below them.
  ReducedLeastSquares out;
  const auto kk = static_cast<std::size_t>(k_);
  std::vector<std::size_t> kept;  // (cell, row) of each row of R_Z that is not 0
  for (std::size_t c = 0; c < cells_; ++c) {
    double* b = block.data() + start[c] * w;
    const std::size_t rows = start[c + 1] - start[c];
    const auto at = [b, w](std::size_t i, std::size_t j) -> double& { return b[i * w + j]; };
    const std::size_t steps = std::min(rows, kk);
    for (std::size_t j = 0; j < steps; ++j) {
      double norm_sq = 0.0;
      for (std::size_t i = j; i < rows; ++i) norm_sq += at(i, j) * at(i, j);
      if (norm_sq == 0.0) continue;
      // H = I − v·vᵀ/β, v = x − α·e₁, β = vᵀv/2 = |x|² − α·x₀.
      const double x0 = at(j, j);
      const double alpha = x0 > 0.0 ? -std::sqrt(norm_sq) : std::sqrt(norm_sq);
      const double beta = norm_sq - alpha * x0;
      at(j, j) = x0 - alpha;
      for (std::size_t l = j + 1; l < w; ++l) {
        double dot = 0.0;
        for (std::size_t i = j; i < rows; ++i) dot += at(i, j) * at(i, l);
        const double f = dot / beta;
        for (std::size_t i = j; i < rows; ++i) at(i, l) -= f * at(i, j);
      }
      at(j, j) = alpha;
      for (std::size_t i = j + 1; i < rows; ++i) at(i, j) = 0.0;  // v's place: R is 0 there
    }
    for (std::size_t i = 0; i < steps; ++i) {
      bool zero = true;
      for (std::size_t j = i; j < kk; ++j) zero = zero && at(i, j) == 0.0;
      if (zero) {
        out.outside_sq += at(i, kk) * at(i, kk);
      } else {
        kept.push_back(start[c] + i);
      }
    }
    for (std::size_t i = steps; i < rows; ++i) out.outside_sq += at(i, kk) * at(i, kk);
  }
  // R_Z·U: Z's row (1, w₁, w₂, dense) gives (1 − w₁, w₁) at the first
  // curve's segment, (1 − w₂, w₂) at the second's, the dense values.
  const auto m = static_cast<Eigen::Index>(kept.size());
  out.a = Eigen::MatrixXd::Zero(m + extra_rows, cols());
  out.b = Eigen::VectorXd::Zero(m + extra_rows);
  out.rows = static_cast<Eigen::Index>(n) + extra_rows;
  const auto second0 = static_cast<Eigen::Index>(bp_first_.size());
  const Eigen::Index dense0 = second0 + static_cast<Eigen::Index>(bp_second_.size());
  const int zd = bp_second_.empty() ? 2 : 3;  // Z's first dense column
  std::size_t c = 0;
  for (Eigen::Index row = 0; row < m; ++row) {
    const std::size_t r = kept[static_cast<std::size_t>(row)];
    while (start[c + 1] <= r) ++c;
    const double* t = block.data() + r * w;
    const auto lo1 = static_cast<Eigen::Index>(c / segments_second_);
    out.a(row, lo1) += t[0] - t[1];
    if (bp_first_.size() > 1) out.a(row, lo1 + 1) += t[1];
    if (!bp_second_.empty()) {
      const Eigen::Index lo2 = second0 + static_cast<Eigen::Index>(c % segments_second_);
      out.a(row, lo2) += t[0] - t[2];
      if (bp_second_.size() > 1) out.a(row, lo2 + 1) += t[2];
    }
    for (int e = 0; e < dense_; ++e) out.a(row, dense0 + e) = t[zd + e];
    out.b(row) = t[k_];
  }
  return out;
}

double PwlLeastSquares::ResidualSquared(const Eigen::VectorXd& c, int rhs) const {
  const auto second0 = static_cast<Eigen::Index>(bp_first_.size());
  const Eigen::Index dense0 = second0 + static_cast<Eigen::Index>(bp_second_.size());
  const int zd = bp_second_.empty() ? 2 : 3;
  double sum = 0.0;
  for (std::size_t i = 0; i < cell_.size(); ++i) {
    const double* t = z_.data() + i * static_cast<std::size_t>(width_);
    const auto lo1 = static_cast<Eigen::Index>(cell_[i] / segments_second_);
    // The row of A times c.
    double v = (1.0 - t[1]) * c(lo1) + (t[1] != 0.0 ? t[1] * c(lo1 + 1) : 0.0);
    if (!bp_second_.empty()) {
      const Eigen::Index lo2 = second0 + static_cast<Eigen::Index>(cell_[i] % segments_second_);
      v += (1.0 - t[2]) * c(lo2) + (t[2] != 0.0 ? t[2] * c(lo2 + 1) : 0.0);
    }
    for (int e = 0; e < dense_; ++e) v += t[zd + e] * c(dense0 + e);
    const double r = v - t[k_ + rhs];
    sum += r * r;
  }
  return sum;
}

Eigen::VectorXd SolveNonNegative(const Eigen::MatrixXd& a, const Eigen::VectorXd& b) {
  const Eigen::Index m = a.cols();
  if (a.rows() == 0 || m == 0 || b.size() != a.rows()) {
    return SolveTruncatedSvd(a, b).c;  // throws with the reason
  }
  std::vector<bool> free(static_cast<std::size_t>(m), false);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(m);
  const double tol = 1e-12 * std::max(1.0, a.norm() * b.norm());
  // Least squares on the free columns, zero elsewhere.
  const auto solve_free = [&]() {
    std::vector<Eigen::Index> cols;
    for (Eigen::Index j = 0; j < m; ++j)
      if (free[static_cast<std::size_t>(j)]) cols.push_back(j);
    Eigen::MatrixXd af(a.rows(), static_cast<Eigen::Index>(cols.size()));
    for (std::size_t k = 0; k < cols.size(); ++k)
      af.col(static_cast<Eigen::Index>(k)) = a.col(cols[k]);
    const Eigen::VectorXd zf = SolveTruncatedSvd(std::move(af), b).c;
    Eigen::VectorXd z = Eigen::VectorXd::Zero(m);
    for (std::size_t k = 0; k < cols.size(); ++k) z(cols[k]) = zf(static_cast<Eigen::Index>(k));
    return z;
  };
  for (Eigen::Index outer = 0; outer < 3 * m + 3; ++outer) {
    const Eigen::VectorXd w = a.transpose() * (b - a * x);  // −gradient / 2
    Eigen::Index best = -1;
    for (Eigen::Index j = 0; j < m; ++j) {
      if (!free[static_cast<std::size_t>(j)] && w(j) > tol && (best < 0 || w(j) > w(best)))
        best = j;
    }
    if (best < 0) break;  // Kuhn–Tucker conditions hold
    free[static_cast<std::size_t>(best)] = true;
    for (Eigen::Index inner = 0; inner <= m; ++inner) {
      const Eigen::VectorXd z = solve_free();
      double alpha = 1.0;
      Eigen::Index blocking = -1;
      for (Eigen::Index j = 0; j < m; ++j) {
        if (free[static_cast<std::size_t>(j)] && z(j) <= 0.0) {
          const double t = x(j) / (x(j) - z(j));
          if (t < alpha) alpha = t, blocking = j;
        }
      }
      if (blocking < 0) {
        x = z;
        break;
      }
      x += alpha * (z - x);
      for (Eigen::Index j = 0; j < m; ++j) {
        if (free[static_cast<std::size_t>(j)] && (j == blocking || x(j) <= 0.0)) {
          free[static_cast<std::size_t>(j)] = false;
          x(j) = 0.0;
        }
      }
    }
  }
  return x;
}

void SetPwlBasisRow(Eigen::MatrixXd& a, Eigen::Index row, Eigen::Index col0,
                    std::span<const double> bp, double x, double scale) {
  const BasisWeights bw = PiecewiseLinear::Basis(bp, x);  // Eq. 4.30
  const Eigen::Index lo = col0 + static_cast<Eigen::Index>(bw.index_lo);
  a(row, lo) += scale * bw.weight_lo;
  if (bp.size() > 1) a(row, lo + 1) += scale * bw.weight_hi;
}

std::vector<double> BreakpointSupport(std::span<const double> bp, std::span<const double> x) {
  std::vector<double> support(bp.size(), 0.0);
  if (bp.empty()) return support;
  std::size_t segment = 0;  // the samples' sweep: the scan from the last segment
  for (double xi : x) {
    const BasisWeights bw = PiecewiseLinear::Basis(bp, xi, segment);
    support[bw.index_lo] += bw.weight_lo;
    if (bp.size() > 1) support[bw.index_lo + 1] += bw.weight_hi;
  }
  return support;
}

std::vector<std::string> SupportWarnings(const std::string& curve, const std::string& unit,
                                         std::span<const double> bp,
                                         std::span<const double> support, double min_support) {
  std::vector<std::string> out;
  for (std::size_t j = 0; j < bp.size() && j < support.size(); ++j) {
    if (support[j] < min_support) {
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "%s: breakpoint %.4g %s has support %.3g samples (under-determined)",
                    curve.c_str(), bp[j], unit.c_str(), support[j]);
      out.emplace_back(buf);
    }
  }
  return out;
}

}  // namespace fesbench::model
