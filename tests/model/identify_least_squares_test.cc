#include "model/identify_least_squares.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "model/piecewise_linear.h"

namespace fesbench::model {
namespace {

TEST(SolveTruncatedSvd, RecoversExactLinearModel) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::MatrixXd a(200, 4);
  for (Eigen::Index i = 0; i < a.rows(); ++i)
    for (Eigen::Index j = 0; j < a.cols(); ++j) a(i, j) = u(rng) * std::pow(10.0, j);
  const Eigen::Vector4d truth(1.5, -2.0, 0.25, 3e-3);
  const auto sol = SolveTruncatedSvd(a, a * truth);
  EXPECT_EQ(sol.rank, 4);
  EXPECT_LT((sol.c - truth).norm(), 1e-10);
  EXPECT_LT(sol.rms, 1e-10);
}

TEST(SolveTruncatedSvd, ZeroesNullDirectionGivingShortestSolution) {
  // Two identical columns: only their sum is determined; the shortest
  // solution splits it equally (Eq. 4.26).
  Eigen::MatrixXd a(50, 2);
  Eigen::VectorXd b(50);
  for (int i = 0; i < 50; ++i) {
    a(i, 0) = a(i, 1) = i * 0.1;
    b(i) = 4.0 * i * 0.1;
  }
  const auto sol = SolveTruncatedSvd(a, b);
  EXPECT_EQ(sol.rank, 1);
  EXPECT_NEAR(sol.c(0), 2.0, 1e-10);
  EXPECT_NEAR(sol.c(1), 2.0, 1e-10);
}

TEST(SolveTruncatedSvd, FitsPiecewiseLinearCurveThroughItsBasis) {
  const PiecewiseLinear truth({0, 10, 20, 30, 40}, {1.0, -2.0, 0.5, 3.0, 2.0});
  const std::vector<double> bp = truth.x();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-5.0, 45.0);
  const int n = 300;
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, 5);
  Eigen::VectorXd b(n);
  for (int i = 0; i < n; ++i) {
    const double x = u(rng);
    SetPwlBasisRow(a, i, 0, bp, x);
    b(i) = truth(x);
  }
  const auto sol = SolveTruncatedSvd(a, b);
  for (int j = 0; j < 5; ++j) EXPECT_NEAR(sol.c(j), truth.y()[static_cast<std::size_t>(j)], 1e-9);
}

TEST(SolveTruncatedSvd, UnvisitedBreakpointIsTruncatedNotBlownUp) {
  const std::vector<double> bp = {0, 1, 2, 3};
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(40, 4);
  Eigen::VectorXd b(40);
  for (int i = 0; i < 40; ++i) {
    const double x = 2.0 * i / 39.0;  // never reaches the segment (2, 3]
    SetPwlBasisRow(a, i, 0, bp, x);
    b(i) = 2.0 * x + 1.0;
  }
  const auto sol = SolveTruncatedSvd(a, b);
  EXPECT_EQ(sol.rank, 3);
  EXPECT_NEAR(sol.c(0), 1.0, 1e-9);
  EXPECT_NEAR(sol.c(2), 5.0, 1e-9);
  EXPECT_NEAR(sol.c(3), 0.0, 1e-12);
  const auto support = BreakpointSupport(bp, std::vector<double>{0.5, 1.5, 2.0});
  EXPECT_NEAR(support[0], 0.5, 1e-12);
  EXPECT_NEAR(support[1], 1.0, 1e-12);
  EXPECT_NEAR(support[2], 1.5, 1e-12);
  EXPECT_NEAR(support[3], 0.0, 1e-12);
  EXPECT_EQ(SupportWarnings("c", "u", bp, support, 1.0).size(), 2u);
}

// The truncated-SVD solution (Eqs. 4.19–4.26) of the column-scaled A taken
// directly: the reference the solver's QR and eigendecomposition paths are
// held to.
LeastSquaresSolution ReferenceTruncatedSvd(const Eigen::MatrixXd& a, const Eigen::VectorXd& b,
                                           double relative_tolerance) {
  Eigen::VectorXd scale(a.cols());
  for (Eigen::Index j = 0; j < a.cols(); ++j) scale(j) = 1.0 / a.col(j).norm();
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(a * scale.asDiagonal(),
                                              Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd& w = svd.singularValues();
  Eigen::VectorXd p = Eigen::VectorXd::Zero(w.size());
  LeastSquaresSolution out;
  for (Eigen::Index j = 0; j < w.size(); ++j) {
    if (w(j) > relative_tolerance * w(0)) {
      p(j) = svd.matrixU().col(j).dot(b) / w(j);
      ++out.rank;
    }
  }
  out.c = scale.asDiagonal() * (svd.matrixV() * p);
  out.rms = std::sqrt((a * out.c - b).squaredNorm() / static_cast<double>(a.rows()));
  out.singular_values = w;
  return out;
}

// The active fit's design (Eq. 4.40): two piecewise-linear bases and a
// constant, rank deficient by two (each basis sums to the constant), the
// other singular values within a factor of 4 of each other: the spectrum
// separates, and the solver takes it through AᵀA's eigendecomposition.
// It must give the SVD's rank and, with the null directions zeroed, its
// solution to 1e-10 (kept λ_j ≥ 1e-4·λ_max: ~5e-11 from the squaring).
TEST(SolveTruncatedSvd, SeparatedSpectrumMatchesTheSvd) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> angle(0.0, 110.0), velocity(-300.0, 300.0);
  std::normal_distribution<double> noise(0.0, 0.05);
  const std::vector<double> bp_a = {0, 11, 22, 33, 44, 55, 66, 77, 88, 99, 110};
  const std::vector<double> bp_v = {-300, -240, -180, -120, -60, 0, 60, 120, 180, 240, 300};
  const int n = 1500;
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, 23);
  Eigen::VectorXd b(n);
  for (int i = 0; i < n; ++i) {
    const double th = angle(rng), om = velocity(rng);
    SetPwlBasisRow(a, i, 0, bp_a, th);
    SetPwlBasisRow(a, i, 11, bp_v, om);
    a(i, 22) = 1.0;
    b(i) = std::sin(th / 30.0) - 1e-3 * om + noise(rng);
  }
  const LeastSquaresSolution ref = ReferenceTruncatedSvd(a, b, 1e-10);
  ASSERT_EQ(ref.rank, 21);
  ASSERT_GT(ref.singular_values(20), 0.25 * ref.singular_values(0));
  const LeastSquaresSolution sol = SolveTruncatedSvd(a, b);
  EXPECT_EQ(sol.rank, 21);
  EXPECT_LT((sol.c - ref.c).norm(), 1e-10 * ref.c.norm());
  EXPECT_NEAR(sol.rms, ref.rms, 1e-12 * ref.rms);
  for (Eigen::Index j = 0; j < 21; ++j) {
    EXPECT_NEAR(sol.singular_values(j), ref.singular_values(j), 1e-10 * ref.singular_values(0));
  }
  EXPECT_LT(sol.singular_values(21), 1e-12 * sol.singular_values(0));
}

// Singular values spread over 1 … 1e-7 (all kept at 1e-10; the columns
// mixed by a random rotation so that scaling them to unit norm keeps the
// spread) and one exact null direction: AᵀA cannot resolve the small ones
// (λ ~ 1e-14·λ_max), so the solver must take the SVD; a solution through
// AᵀA would be off by ~1e-2 here. The SVD of R against the SVD of A:
// ~ε·κ ≈ 1e-9.
TEST(SolveTruncatedSvd, SpreadSpectrumFallsBackToTheSvd) {
  std::mt19937 rng(5);
  std::normal_distribution<double> n01;
  const int n = 300;
  const auto orthonormal = [&](int rows, int cols) {
    Eigen::MatrixXd g(rows, cols);
    for (Eigen::Index i = 0; i < g.size(); ++i) g.data()[i] = n01(rng);
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(g);
    return Eigen::MatrixXd(qr.householderQ() * Eigen::MatrixXd::Identity(rows, cols));
  };
  const Eigen::Vector<double, 5> w(1.0, 1e-2, 1e-4, 1e-6, 1e-7);
  Eigen::MatrixXd a(n, 6);
  a.leftCols(5) = orthonormal(n, 5) * w.asDiagonal() * orthonormal(5, 5).transpose();
  a.col(5) = a.col(0);  // the null direction: c₀ − c₅
  Eigen::VectorXd b(n);
  for (Eigen::Index i = 0; i < n; ++i) b(i) = n01(rng);
  const LeastSquaresSolution ref = ReferenceTruncatedSvd(a, b, 1e-10);
  ASSERT_EQ(ref.rank, 5);
  const LeastSquaresSolution sol = SolveTruncatedSvd(a, b);
  EXPECT_EQ(sol.rank, 5);
  EXPECT_LT((sol.c - ref.c).norm(), 1e-7 * ref.c.norm());
  EXPECT_NEAR(sol.rms, ref.rms, 1e-9 * ref.rms);
}

// The cell-reduced rows against the dense design they stand for: the same
// solution (1e-10 relative: the QR of the reduced rows is another
// orthogonal reduction of the same A), rank and rms, and the residual of
// any c to 1e-10 relative. Two curves with samples beyond both ends (held
// ends), a dense column and two right-hand sides; one curve; a curve of
// one breakpoint.
TEST(PwlLeastSquares, ReducedRowsSolveAsTheDenseDesign) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> angle(-10.0, 120.0), velocity(-350.0, 350.0);
  std::normal_distribution<double> n01;
  const std::vector<double> bp_a = {0, 20, 40, 60, 80, 100, 110};
  const std::vector<double> bp_v = {-300, -150, -50, 0, 50, 150, 300};
  const std::vector<double> one = {5.0};
  const int n = 800;
  for (const auto& [first, second] :
       {std::pair{&bp_a, &bp_v}, std::pair{&bp_v, (const std::vector<double>*)nullptr},
        std::pair{&one, &bp_v}}) {
    const std::span<const double> second_bp =
        second ? std::span<const double>(*second) : std::span<const double>();
    PwlLeastSquares pwl(*first, second_bp, 1, 2);
    const auto m1 = static_cast<Eigen::Index>(first->size());
    const auto m2 = static_cast<Eigen::Index>(second_bp.size());
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, m1 + m2 + 1);
    Eigen::MatrixXd b(n, 2);
    for (int i = 0; i < n; ++i) {
      // A sweep (the hints' case) with jumps.
      const double x1 = i % 97 == 0 ? angle(rng) : 55.0 + 60.0 * std::sin(0.01 * i);
      const double x2 = velocity(rng);
      const double dense = n01(rng);
      const double rhs[2] = {std::cos(x1 / 40.0) + 1e-3 * x2 + 0.5 * dense + 0.1 * n01(rng),
                             n01(rng)};
      pwl.AddRow(x1, x2, std::span(&dense, 1), rhs);
      SetPwlBasisRow(a, i, 0, *first, x1);
      if (second) SetPwlBasisRow(a, i, m1, second_bp, x2);
      a(i, m1 + m2) = dense;
      b(i, 0) = rhs[0];
      b(i, 1) = rhs[1];
    }
    ASSERT_EQ(pwl.rows(), n);
    ASSERT_EQ(pwl.cols(), a.cols());
    for (int q = 0; q < 2; ++q) {
      const Eigen::VectorXd bq = b.col(q);
      const LeastSquaresSolution dense_sol = SolveTruncatedSvd(a, bq);
      ReducedLeastSquares reduced = pwl.Reduced(q);
      EXPECT_LT(reduced.a.rows(), n / 4);
      const LeastSquaresSolution sol = SolveTruncatedSvd(std::move(reduced));
      EXPECT_EQ(sol.rank, dense_sol.rank);
      EXPECT_LT((sol.c - dense_sol.c).norm(), 1e-10 * dense_sol.c.norm());
      EXPECT_NEAR(sol.rms, dense_sol.rms, 1e-10 * dense_sol.rms);
      for (const Eigen::VectorXd& c : {dense_sol.c, Eigen::VectorXd(dense_sol.c.array() + 0.3)}) {
        const double direct = (a * c - bq).squaredNorm();
        EXPECT_NEAR(pwl.ResidualSquared(c, q), direct, 1e-10 * direct);
      }
    }
  }
}

// Rows below the reduced ones (Reduced's extra_rows) count in the rms.
TEST(PwlLeastSquares, ExtraRowsJoinTheProblem) {
  const std::vector<double> bp = {0.0, 1.0, 2.0};
  PwlLeastSquares pwl(bp, {}, 0, 1);
  const double rhs[3] = {1.0, 2.0, 4.0};
  for (int i = 0; i < 3; ++i) pwl.AddRow(static_cast<double>(i), 0.0, {}, std::span(&rhs[i], 1));
  ReducedLeastSquares reduced = pwl.Reduced(0, 1);
  ASSERT_EQ(reduced.rows, 4);
  // c₀ − 2c₁ + c₂ = 0 with weight 1: the curve is pulled towards a line.
  const Eigen::Index last = reduced.a.rows() - 1;
  reduced.a.row(last) << 1.0, -2.0, 1.0;
  Eigen::MatrixXd a(4, 3);
  a << 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, -2, 1;
  const LeastSquaresSolution dense_sol = SolveTruncatedSvd(a, Eigen::Vector4d(1, 2, 4, 0));
  const LeastSquaresSolution sol = SolveTruncatedSvd(std::move(reduced));
  EXPECT_LT((sol.c - dense_sol.c).norm(), 1e-12);
  EXPECT_NEAR(sol.rms, dense_sol.rms, 1e-12);
}

TEST(SolveTruncatedSvd, RejectsBrokenPreconditions) {
  EXPECT_THROW(SolveTruncatedSvd(Eigen::MatrixXd(3, 2), Eigen::VectorXd(4)), std::invalid_argument);
  EXPECT_THROW(SolveTruncatedSvd(Eigen::MatrixXd(0, 2), Eigen::VectorXd(0)), std::invalid_argument);
  EXPECT_THROW(SolveTruncatedSvd(Eigen::MatrixXd::Ones(3, 2), Eigen::VectorXd::Ones(3), 0.0),
               std::invalid_argument);
}

TEST(SolveNonNegative, ClosedForms) {
  // Identity: the negative coordinate is clipped.
  Eigen::Vector2d x = SolveNonNegative(Eigen::Matrix2d::Identity(), Eigen::Vector2d(1.0, -2.0));
  EXPECT_NEAR(x(0), 1.0, 1e-12);
  EXPECT_EQ(x(1), 0.0);
  // A falling line: slope ≥ 0 forces slope 0 and the mean as intercept.
  Eigen::MatrixXd a(3, 2);
  a << 1, 0, 1, 1, 1, 2;
  x = SolveNonNegative(a, Eigen::Vector3d(2.0, 1.0, 0.0));
  EXPECT_NEAR(x(0), 1.0, 1e-12);
  EXPECT_EQ(x(1), 0.0);
  // A feasible unconstrained solution is returned unchanged.
  x = SolveNonNegative(a, Eigen::Vector3d(1.0, 2.0, 3.0));
  EXPECT_NEAR(x(0), 1.0, 1e-12);
  EXPECT_NEAR(x(1), 1.0, 1e-12);
}

// Against brute force: the best feasible least-squares solution over every
// choice of zeroed columns.
TEST(SolveNonNegative, MatchesExhaustiveSearch) {
  std::mt19937 rng(17);
  std::normal_distribution<double> n01;
  for (int trial = 0; trial < 50; ++trial) {
    Eigen::MatrixXd a(8, 4);
    Eigen::VectorXd b(8);
    for (Eigen::Index i = 0; i < a.size(); ++i) a.data()[i] = n01(rng);
    for (Eigen::Index i = 0; i < b.size(); ++i) b(i) = n01(rng);
    double best = 1e300;
    for (int mask = 0; mask < 16; ++mask) {
      std::vector<Eigen::Index> cols;
      for (Eigen::Index j = 0; j < 4; ++j)
        if (mask & (1 << j)) cols.push_back(j);
      Eigen::VectorXd full = Eigen::VectorXd::Zero(4);
      if (!cols.empty()) {
        Eigen::MatrixXd af(8, static_cast<Eigen::Index>(cols.size()));
        for (std::size_t k = 0; k < cols.size(); ++k)
          af.col(static_cast<Eigen::Index>(k)) = a.col(cols[k]);
        const Eigen::VectorXd z = af.colPivHouseholderQr().solve(b);
        for (std::size_t k = 0; k < cols.size(); ++k)
          full(cols[k]) = z(static_cast<Eigen::Index>(k));
      }
      if (full.minCoeff() >= 0.0) best = std::min(best, (a * full - b).squaredNorm());
    }
    const Eigen::VectorXd x = SolveNonNegative(a, b);
    EXPECT_GE(x.minCoeff(), 0.0);
    EXPECT_NEAR((a * x - b).squaredNorm(), best, 1e-9) << "trial " << trial;
  }
}

}  // namespace
}  // namespace fesbench::model
