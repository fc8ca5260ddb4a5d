#include "model/conditioning.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#include "model/grid_golden_search.h"

namespace fesbench::model {
namespace {

double MeanOf(std::span<const double> v, std::size_t begin, std::size_t end) {
  double s = 0.0;
  for (std::size_t i = begin; i < end; ++i) s += v[i];
  return s / static_cast<double>(end - begin);
}

// Reinsch's banded system for the cubic smoothing spline (Green & Silverman
// 1994, §2.3): Q is n×(n−2) (second divided differences), R (n−2)×(n−2)
// tridiagonal; f = y − λ·Q·γ with (R + λ·QᵀQ)·γ = Qᵀ·y, γ = f'' at the
// interior knots. Woltring's GCVSPL solves the same problem for m = 2.
class ReinschSystem {
 public:
  ReinschSystem(std::span<const double> t, std::span<const double> y) : t_(t), y_(y) {
    const std::size_t n = t.size();
    if (n < 4) throw std::invalid_argument("smoothing spline: need at least 4 samples");
    if (y.size() != n) {
      throw std::invalid_argument("smoothing spline: wrong argument size: expected " +
                                  std::to_string(n) + " values, got " + std::to_string(y.size()));
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (!std::isfinite(t[i]) || !std::isfinite(y[i])) {
        throw std::invalid_argument("smoothing spline: non-finite value at sample " +
                                    std::to_string(i));
      }
      if (i > 0 && !(t[i] > t[i - 1])) {
        throw std::invalid_argument("smoothing spline: t not strictly increasing at sample " +
                                    std::to_string(i));
      }
    }
    m_ = n - 2;
    h_.resize(n - 1);
    for (std::size_t i = 0; i + 1 < n; ++i) h_[i] = t[i + 1] - t[i];
    qa_.resize(m_), qb_.resize(m_), qc_.resize(m_);
    r0_.resize(m_), r1_.assign(m_, 0.0);
    p0_.resize(m_), p1_.assign(m_, 0.0), p2_.assign(m_, 0.0);
    qty_.resize(m_);
    for (std::size_t j = 0; j < m_; ++j) {
      const std::size_t k = j + 1;  // knot of column j
      qa_[j] = 1.0 / h_[k - 1];
      qc_[j] = 1.0 / h_[k];
      qb_[j] = -qa_[j] - qc_[j];
      r0_[j] = (h_[k - 1] + h_[k]) / 3.0;
      if (j + 1 < m_) r1_[j] = h_[k] / 6.0;
      qty_[j] = qa_[j] * y[k - 1] + qb_[j] * y[k] + qc_[j] * y[k + 1];
    }
    for (std::size_t j = 0; j < m_; ++j) {
      p0_[j] = qa_[j] * qa_[j] + qb_[j] * qb_[j] + qc_[j] * qc_[j];
      if (j + 1 < m_) p1_[j] = qb_[j] * qa_[j + 1] + qc_[j] * qb_[j + 1];
      if (j + 2 < m_) p2_[j] = qc_[j] * qa_[j + 2];
    }
    d_.resize(m_), l1_.resize(m_), l2_.resize(m_), gamma_.resize(m_);
    s0_.resize(m_), s1_.resize(m_), s2_.resize(m_);
  }

  double mean_spacing() const { return (t_.back() - t_.front()) / static_cast<double>(h_.size()); }

  // Factorises B = R + λQᵀQ = L·D·Lᵀ and solves for γ.
  void Solve(double lambda) {
    lambda_ = lambda;
    for (std::size_t j = 0; j < m_; ++j) {
      const double b0 = r0_[j] + lambda * p0_[j];
      const double b1 = r1_[j] + lambda * p1_[j];
      const double b2 = lambda * p2_[j];
      double dj = b0;
      if (j >= 1) dj -= l1_[j - 1] * l1_[j - 1] * d_[j - 1];
      if (j >= 2) dj -= l2_[j - 2] * l2_[j - 2] * d_[j - 2];
      d_[j] = dj;
      double c1 = b1;
      if (j >= 1) c1 -= l1_[j - 1] * d_[j - 1] * l2_[j - 1];
      l1_[j] = (j + 1 < m_) ? c1 / dj : 0.0;
      l2_[j] = (j + 2 < m_) ? b2 / dj : 0.0;
    }
    for (std::size_t j = 0; j < m_; ++j) {
      double z = qty_[j];
      if (j >= 1) z -= l1_[j - 1] * gamma_[j - 1];
      if (j >= 2) z -= l2_[j - 2] * gamma_[j - 2];
      gamma_[j] = z;
    }
    for (std::size_t j = 0; j < m_; ++j) gamma_[j] /= d_[j];
    for (std::size_t jj = m_; jj-- > 0;) {
      double g = gamma_[jj];
      if (jj + 1 < m_) g -= l1_[jj] * gamma_[jj + 1];
      if (jj + 2 < m_) g -= l2_[jj] * gamma_[jj + 2];
      gamma_[jj] = g;
    }
  }

  // (Q·γ)_i.
  double QGamma(std::size_t i) const {
    double s = 0.0;
    if (i >= 2) s += qc_[i - 2] * gamma_[i - 2];                // column of knot i−1
    if (i >= 1 && i - 1 < m_) s += qb_[i - 1] * gamma_[i - 1];  // knot i
    if (i < m_) s += qa_[i] * gamma_[i];                        // knot i+1
    return s;
  }

  double Rss() const {
    double rss = 0.0;
    for (std::size_t i = 0; i < t_.size(); ++i) {
      const double r = lambda_ * QGamma(i);
      rss += r * r;
    }
    return rss;
  }

  // tr(I − A(λ)) = λ·tr(B⁻¹·QᵀQ), from the central band of B⁻¹
  // (Hutchinson & de Hoog 1985): Σ_ij = δ_ij/d_i − Σ_k>i L_ki·Σ_kj.
  double TraceResidualOperator() {
    for (std::size_t i = m_; i-- > 0;) {
      const double s0n = i + 1 < m_ ? s0_[i + 1] : 0.0;
      const double s1n = i + 1 < m_ ? s1_[i + 1] : 0.0;
      const double s0nn = i + 2 < m_ ? s0_[i + 2] : 0.0;
      s2_[i] = -l1_[i] * s1n - l2_[i] * s0nn;
      s1_[i] = -l1_[i] * s0n - l2_[i] * s1n;
      s0_[i] = 1.0 / d_[i] - l1_[i] * s1_[i] - l2_[i] * s2_[i];
    }
    double tr = 0.0;
    for (std::size_t j = 0; j < m_; ++j) {
      tr += s0_[j] * p0_[j] + 2.0 * s1_[j] * p1_[j] + 2.0 * s2_[j] * p2_[j];
    }
    return lambda_ * tr;
  }

  double Gcv() {
    const double n = static_cast<double>(t_.size());
    const double tr = TraceResidualOperator();
    if (!(tr > 0.0)) return std::numeric_limits<double>::infinity();
    return n * Rss() / (tr * tr);
  }

  SmoothingSplineFit Result() {
    const std::size_t n = t_.size();
    SmoothingSplineFit fit;
    fit.lambda = lambda_;
    fit.value.resize(n);
    std::vector<double> g(n, 0.0);  // f'' at every knot, natural ends
    for (std::size_t j = 0; j < m_; ++j) g[j + 1] = gamma_[j];
    double rss = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const double r = lambda_ * QGamma(i);
      fit.value[i] = y_[i] - r;
      rss += r * r;
    }
    fit.first.resize(n);
    for (std::size_t i = 0; i + 1 < n; ++i) {
      fit.first[i] =
          (fit.value[i + 1] - fit.value[i]) / h_[i] - h_[i] * (2.0 * g[i] + g[i + 1]) / 6.0;
    }
    const double hl = h_[n - 2];
    fit.first[n - 1] =
        (fit.value[n - 1] - fit.value[n - 2]) / hl + hl * (g[n - 2] + 2.0 * g[n - 1]) / 6.0;
    fit.second = std::move(g);
    fit.residual_rms = std::sqrt(rss / static_cast<double>(n));
    const double tr = TraceResidualOperator();
    fit.effective_dof = static_cast<double>(n) - tr;
    fit.gcv = tr > 0.0 ? static_cast<double>(n) * rss / (tr * tr)
                       : std::numeric_limits<double>::infinity();
    return fit;
  }

 private:
  std::span<const double> t_, y_;
  std::size_t m_ = 0;
  double lambda_ = 0.0;
  std::vector<double> h_, qa_, qb_, qc_, r0_, r1_, p0_, p1_, p2_, qty_;
  std::vector<double> d_, l1_, l2_, gamma_, s0_, s1_, s2_;
};

}  // namespace

double TorqueOffset(std::span<const double> torque_nm, std::size_t count) {
  if (count == 0 || torque_nm.size() < count) {
    throw std::invalid_argument("TorqueOffset: need at least " + std::to_string(count) +
                                " samples (and count > 0), got " +
                                std::to_string(torque_nm.size()));
  }
  return MeanOf(torque_nm, 0, count);
}

std::vector<double> RemoveTorqueOffset(std::span<const double> torque_nm, std::size_t count) {
  const double offset = TorqueOffset(torque_nm, count);
  std::vector<double> out(torque_nm.begin(), torque_nm.end());
  for (double& v : out) v -= offset;
  return out;
}

std::vector<PositionHold> DetectHolds(std::span<const double> t_s,
                                      std::span<const double> angle_deg,
                                      std::span<const double> torque_nm,
                                      std::span<const double> accel_deg_s2,
                                      const HoldOptions& options) {
  const std::size_t n = t_s.size();
  if (n < 2 || angle_deg.size() != n) {
    throw std::invalid_argument("DetectHolds: t_s and angle_deg must have the same length >= 2");
  }
  if ((!torque_nm.empty() && torque_nm.size() != n) ||
      (!accel_deg_s2.empty() && accel_deg_s2.size() != n)) {
    throw std::invalid_argument("DetectHolds: torque/accel columns must match t_s in length");
  }
  if (options.average_samples == 0) {
    throw std::invalid_argument("DetectHolds: average_samples must be positive");
  }
  if (!(options.speed_span_s >= 0.0)) {
    throw std::invalid_argument("DetectHolds: speed_span_s must be >= 0");
  }
  // Half the span in samples (at least one neighbour each side).
  const double dt = (t_s[n - 1] - t_s[0]) / static_cast<double>(n - 1);
  const auto half = std::max<std::size_t>(
      1, static_cast<std::size_t>(std::llround(0.5 * options.speed_span_s / dt)));
  std::vector<bool> still(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t a = i >= half ? i - half : 0;
    const std::size_t b = std::min(n - 1, i + half);
    const double speed = std::abs(angle_deg[b] - angle_deg[a]) / (t_s[b] - t_s[a]);
    still[i] = speed < options.max_speed_deg_s;
  }
  std::vector<PositionHold> holds;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (std::size_t i = 0; i < n;) {
    if (!still[i]) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < n && still[j]) ++j;
    if (t_s[j - 1] - t_s[i] >= options.min_duration_s) {
      const std::size_t w0 = j - std::min(options.average_samples, j - i);
      PositionHold h;
      h.begin = i;
      h.end = j;
      h.angle_deg = MeanOf(angle_deg, w0, j);
      h.torque_nm = torque_nm.empty() ? nan : MeanOf(torque_nm, w0, j);
      h.accel_deg_s2 = accel_deg_s2.empty() ? nan : MeanOf(accel_deg_s2, w0, j);
      holds.push_back(h);
    }
    i = j;
  }
  return holds;
}

PiecewiseLinear AverageHoldsByAngle(std::span<const PositionHold> holds, bool acceleration,
                                    double tolerance_deg) {
  if (holds.empty()) throw std::invalid_argument("AverageHoldsByAngle: no holds");
  std::vector<PositionHold> sorted(holds.begin(), holds.end());
  std::sort(sorted.begin(), sorted.end(),
            [](const PositionHold& a, const PositionHold& b) { return a.angle_deg < b.angle_deg; });
  std::vector<double> x, y;
  for (std::size_t i = 0; i < sorted.size();) {
    std::size_t j = i;
    double sa = 0.0, sv = 0.0;
    while (j < sorted.size() && sorted[j].angle_deg - sorted[i].angle_deg <= tolerance_deg) {
      sa += sorted[j].angle_deg;
      sv += acceleration ? sorted[j].accel_deg_s2 : sorted[j].torque_nm;
      ++j;
    }
    const double cnt = static_cast<double>(j - i);
    const double xa = sa / cnt;
    if (!x.empty() && !(xa > x.back())) {
      // Merged groups can only collide within rounding; nudge to keep order.
      x.push_back(std::nextafter(x.back(), std::numeric_limits<double>::infinity()));
    } else {
      x.push_back(xa);
    }
    y.push_back(sv / cnt);
    i = j;
  }
  if (!std::all_of(y.begin(), y.end(), [](double v) { return std::isfinite(v); })) {
    throw std::invalid_argument("AverageHoldsByAngle: the holds lack the requested channel");
  }
  return PiecewiseLinear(std::move(x), std::move(y));
}

PiecewiseLinear AccelerometerCalibration(std::span<const double> t_s,
                                         std::span<const double> angle_deg,
                                         std::span<const double> accel_deg_s2,
                                         const HoldOptions& options) {
  if (accel_deg_s2.size() != t_s.size()) {
    throw std::invalid_argument("AccelerometerCalibration: accel column missing or wrong length");
  }
  const auto holds = DetectHolds(t_s, angle_deg, {}, accel_deg_s2, options);
  if (holds.empty()) throw std::invalid_argument("AccelerometerCalibration: no position holds");
  return AverageHoldsByAngle(holds, /*acceleration=*/true);
}

std::vector<double> CorrectAcceleration(const PiecewiseLinear& calibration,
                                        std::span<const double> angle_deg,
                                        std::span<const double> accel_deg_s2) {
  if (calibration.empty()) throw std::invalid_argument("CorrectAcceleration: empty table");
  if (angle_deg.size() != accel_deg_s2.size()) {
    throw std::invalid_argument("CorrectAcceleration: angle and accel differ in length");
  }
  std::vector<double> out(accel_deg_s2.size());
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = accel_deg_s2[i] - calibration(angle_deg[i]);
  return out;
}

SmoothingSplineFit SmoothingSpline(std::span<const double> t_s, std::span<const double> y,
                                   double lambda) {
  if (!(lambda >= 0.0) || !std::isfinite(lambda)) {
    throw std::invalid_argument("SmoothingSpline: lambda must be finite and >= 0");
  }
  ReinschSystem sys(t_s, y);
  sys.Solve(lambda);
  return sys.Result();
}

SmoothingSplineFit GcvSmoothingSpline(std::span<const double> t_s, std::span<const double> y) {
  ReinschSystem sys(t_s, y);
  // λ = ρ·h̄³ makes ρ dimensionless: ρ^(1/4) is roughly the smoothing
  // window in samples.
  const double h = sys.mean_spacing();
  const double unit = h * h * h;
  const auto gcv_at = [&](double log10_rho) {
    sys.Solve(unit * std::pow(10.0, log10_rho));
    return sys.Gcv();
  };
  // log10 ρ on a grid of step 1 over [-4, 16], then golden-section
  // refinement within one grid step either side.
  const GridGoldenResult search = GridGoldenSearch(gcv_at, -4.0, 16.0, 20, 20);
  const double x = search.golden.cost > search.grid.cost ? search.grid.x : search.golden.x;
  sys.Solve(unit * std::pow(10.0, x));
  return sys.Result();
}

}  // namespace fesbench::model
