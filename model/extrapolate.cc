#include "model/extrapolate.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "model/units.h"

namespace fesbench::model {
namespace {

// Widths of the end-range exponentials tried, deg (tissue stiffening over
// roughly 5–30° near each end, Fig. 6-19 / I-1).
constexpr double kWidthsDeg[] = {6.0, 8.0, 11.0, 15.0, 20.0, 28.0};

struct Samples {
  std::vector<double> th, y;
};

Samples Sample(const PiecewiseLinear& c, double lo, double hi) {
  Samples s;
  const int n = std::max(2, static_cast<int>(std::ceil(hi - lo)) + 1);
  for (int i = 0; i < n; ++i) {
    const double x = lo + (hi - lo) * i / (n - 1);
    s.th.push_back(x);
    s.y.push_back(c(x));
  }
  return s;
}

// Merges outside breakpoints with the curve's own inside [lo, hi].
PiecewiseLinear Merge(const PiecewiseLinear& c, double lo, double hi, const std::vector<double>& xo,
                      const auto& value_outside) {
  std::vector<double> x, y;
  for (double v : xo) {
    if (v < lo - 0.5) x.push_back(v), y.push_back(value_outside(v));
  }
  x.push_back(lo), y.push_back(c(lo));
  for (std::size_t i = 0; i < c.size(); ++i) {
    if (c.x()[i] > lo + 1e-9 && c.x()[i] < hi - 1e-9) x.push_back(c.x()[i]), y.push_back(c.y()[i]);
  }
  if (hi > lo) x.push_back(hi), y.push_back(c(hi));
  for (double v : xo) {
    if (v > hi + 0.5) x.push_back(v), y.push_back(value_outside(v));
  }
  return PiecewiseLinear(std::move(x), std::move(y));
}

std::vector<double> Grid(double out_lo, double lo, double hi, double out_hi, double step) {
  std::vector<double> g;
  for (double v = lo - step; v > out_lo - 1e-9; v -= step) g.push_back(v);
  if (out_lo < lo && (g.empty() || g.back() > out_lo + 1e-9)) g.push_back(out_lo);
  std::reverse(g.begin(), g.end());
  for (double v = hi + step; v < out_hi + 1e-9; v += step) g.push_back(v);
  if (out_hi > hi && (g.empty() || g.back() < out_hi - 1e-9)) g.push_back(out_hi);
  return g;
}

}  // namespace

double PassiveAngleForm::mgl_nm() const { return std::hypot(a_nm, b_nm); }

double PassiveAngleForm::hang_deg() const {
  // a·sin θ + b·cos θ = R·sin(θ + φ), φ = atan2(b, a): zero at θ = −φ (mod 180°).
  double h = -RadToDeg(std::atan2(b_nm, a_nm));
  while (h < 0.0) h += 180.0;
  while (h >= 180.0) h -= 180.0;
  return h;
}

double PassiveAngleForm::operator()(double th) const {
  const double r = DegToRad(th);
  return a_nm * std::sin(r) + b_nm * std::cos(r) + c_nm -
         ext_nm * std::exp(-(th - lo_deg) / ext_width_deg) +
         flex_nm * std::exp((th - hi_deg) / flex_width_deg);
}

PassiveAngleForm FitPassiveAngleForm(const PiecewiseLinear& torque_angle, double lo, double hi,
                                     double mgl_prior_nm) {
  if (torque_angle.empty()) throw std::invalid_argument("FitPassiveAngleForm: empty curve");
  if (!(hi - lo >= 5.0)) throw std::invalid_argument("FitPassiveAngleForm: range under 5°");
  const Samples s = Sample(torque_angle, lo, hi);
  const auto n = static_cast<Eigen::Index>(s.th.size());
  const bool fixed_gravity = mgl_prior_nm > 0.0 && hi - lo < 60.0;
  PassiveAngleForm best;
  best.rms_nm = std::numeric_limits<double>::infinity();
  // Exponential terms: none, or one width from the grid (k ≥ 0 required).
  std::vector<double> widths = {0.0};
  widths.insert(widths.end(), std::begin(kWidthsDeg), std::end(kWidthsDeg));
  std::vector<double> hangs = {0.0};
  if (fixed_gravity) {
    hangs.clear();
    for (double h = 50.0; h <= 110.0; h += 1.0) hangs.push_back(h);
  }
  for (double we : widths) {
    for (double wf : widths) {
      for (double hang : hangs) {
        const Eigen::Index cols = (fixed_gravity ? 1 : 3) + (we > 0) + (wf > 0);
        Eigen::MatrixXd a(n, cols);
        Eigen::VectorXd b(n);
        for (Eigen::Index i = 0; i < n; ++i) {
          const double th = s.th[static_cast<std::size_t>(i)];
          Eigen::Index k = 0;
          b(i) = s.y[static_cast<std::size_t>(i)];
          if (fixed_gravity) {
            b(i) -= mgl_prior_nm * std::sin(DegToRad(th - hang));
          } else {
            a(i, k++) = std::sin(DegToRad(th));
            a(i, k++) = std::cos(DegToRad(th));
          }
          a(i, k++) = 1.0;
          if (we > 0) a(i, k++) = -std::exp(-(th - lo) / we);
          if (wf > 0) a(i, k++) = std::exp((th - hi) / wf);
        }
        const Eigen::VectorXd c = a.completeOrthogonalDecomposition().solve(b);
        Eigen::Index k = 0;
        PassiveAngleForm f;
        f.lo_deg = lo;
        f.hi_deg = hi;
        if (fixed_gravity) {
          // mgl·sin(θ − h) = mgl·cos h·sin θ − mgl·sin h·cos θ.
          f.a_nm = mgl_prior_nm * std::cos(DegToRad(hang));
          f.b_nm = -mgl_prior_nm * std::sin(DegToRad(hang));
        } else {
          f.a_nm = c(k++);
          f.b_nm = c(k++);
        }
        f.c_nm = c(k++);
        if (we > 0) f.ext_nm = c(k++), f.ext_width_deg = we;
        if (wf > 0) f.flex_nm = c(k++), f.flex_width_deg = wf;
        if (f.ext_nm < 0.0 || f.flex_nm < 0.0) continue;  // tissue only resists
        f.rms_nm = std::sqrt((a * c - b).squaredNorm() / static_cast<double>(n));
        if (f.rms_nm < best.rms_nm - 1e-9) best = f;
      }
    }
  }
  return best;
}

PiecewiseLinear ExtendPassiveAngle(const PiecewiseLinear& c, const PassiveAngleForm& form,
                                   double out_lo, double out_hi, double step) {
  const double lo = form.lo_deg, hi = form.hi_deg;
  const double shift_lo = c(lo) - form(lo), shift_hi = c(hi) - form(hi);
  return Merge(c, lo, hi, Grid(out_lo, lo, hi, out_hi, step),
               [&](double x) { return form(x) + (x < lo ? shift_lo : shift_hi); });
}

PiecewiseLinear ExtendActiveAngle(const PiecewiseLinear& gain, double lo, double hi, double out_lo,
                                  double out_hi, double step) {
  // ln f = q0 + q1·θ + q2·θ² on the positive samples (a Gaussian if q2 < 0).
  const Samples s = Sample(gain, lo, hi);
  std::vector<double> th, lny;
  for (std::size_t i = 0; i < s.th.size(); ++i) {
    if (s.y[i] > 1e-3) th.push_back(s.th[i] - 90.0), lny.push_back(std::log(s.y[i]));
  }
  Eigen::Vector3d q = Eigen::Vector3d::Zero();
  bool gaussian = false;
  if (th.size() >= 5 && hi - lo >= 10.0) {
    Eigen::MatrixXd a(static_cast<Eigen::Index>(th.size()), 3);
    Eigen::VectorXd b(static_cast<Eigen::Index>(th.size()));
    for (std::size_t i = 0; i < th.size(); ++i) {
      const auto r = static_cast<Eigen::Index>(i);
      a(r, 0) = 1.0, a(r, 1) = th[i], a(r, 2) = th[i] * th[i];
      b(r) = lny[i];
    }
    q = a.colPivHouseholderQr().solve(b);
    gaussian = q(2) < 0.0 && std::isfinite(q(2));
  }
  const auto lnq = [&](double x) {
    return q(0) + q(1) * (x - 90.0) + q(2) * (x - 90.0) * (x - 90.0);
  };
  const double g_lo = std::max(0.0, gain(lo)), g_hi = std::max(0.0, gain(hi));
  return Merge(gain, lo, hi, Grid(out_lo, lo, hi, out_hi, step), [&](double x) {
    const double edge = x < lo ? lo : hi;
    const double g_edge = x < lo ? g_lo : g_hi;
    if (!gaussian) return g_edge;
    return std::clamp(g_edge * std::exp(lnq(x) - lnq(edge)), 0.0, g_edge);  // never rising
  });
}

PiecewiseLinear ExtendVelocityCurve(const PiecewiseLinear& c, double lo, double hi, double out_lo,
                                    double out_hi, bool passive) {
  const double s_lo = c.Slope(lo), s_hi = c.Slope(std::nextafter(hi, lo));
  const double y_lo = c(lo), y_hi = c(hi);
  std::vector<double> xo;
  if (out_lo < lo - 0.5) xo.push_back(out_lo);
  // A gain continued to 0 stays 0 from there on: a breakpoint where it gets there.
  if (!passive && s_lo > 0.0 && y_lo > 0.0 && lo - y_lo / s_lo > out_lo + 0.5) {
    xo.push_back(lo - y_lo / s_lo);
  }
  if (!passive && s_hi < 0.0 && y_hi > 0.0 && hi - y_hi / s_hi < out_hi - 0.5) {
    xo.push_back(hi - y_hi / s_hi);
  }
  if (out_hi > hi + 0.5) xo.push_back(out_hi);
  return Merge(c, lo, hi, xo, [&](double x) {
    const double edge = x < lo ? y_lo : y_hi;
    const double slope = x < lo ? s_lo : s_hi;
    const double v = edge + slope * (x - (x < lo ? lo : hi));
    if (passive) return slope >= 0.0 ? v : edge;  // viscous: torque grows with speed
    return std::clamp(v, 0.0, std::max(0.0, edge));
  });
}

std::optional<double> ShareOutsideIdentifiedRanges(const Provenance& p,
                                                   std::span<const double> angle,
                                                   std::span<const double> velocity) {
  if (!velocity.empty() && velocity.size() != angle.size()) {
    throw std::invalid_argument(
        "ShareOutsideIdentifiedRanges: velocity_deg_s and angle_deg differ in length");
  }
  if (angle.empty() || (p.identified_range_deg.empty() && p.identified_range_deg_s.empty())) {
    return std::nullopt;
  }
  std::size_t outside = 0;
  for (std::size_t i = 0; i < angle.size(); ++i) {
    bool out = false;
    for (const auto& [name, r] : p.identified_range_deg) out = out || !r.Contains(angle[i]);
    if (!velocity.empty()) {
      for (const auto& [name, r] : p.identified_range_deg_s) out = out || !r.Contains(velocity[i]);
    }
    outside += out ? 1 : 0;
  }
  return static_cast<double>(outside) / static_cast<double>(angle.size());
}

}  // namespace fesbench::model
