#include "model/identify_simplified.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "model/identify_least_squares.h"
#include "model/units.h"

namespace fesbench::model {
namespace {

struct ActiveSamples {
  std::vector<double> angle, vel, act, tau;
  std::size_t size() const { return tau.size(); }
};

ActiveSamples Collect(std::span<const TrialColumns> trials, const PassiveParams& passive,
                      const ActiveOptions& options, bool positive_only) {
  ActiveSamples s;
  for (const TrialColumns& tr : trials) {
    RequireColumn("IdentifySimplified", "activation", tr.activation, tr.size());
    const auto t_act = ActiveTorque(tr, passive, options.use_measured_torque);
    for (std::size_t i = 0; i < tr.size(); ++i) {
      if (tr.activation[i] < options.min_activation) continue;
      if (positive_only && !(t_act[i] > 0.0)) continue;
      s.angle.push_back(tr.angle_deg[i]);
      s.vel.push_back(tr.velocity_deg_s[i]);
      s.act.push_back(tr.activation[i]);
      s.tau.push_back(t_act[i]);
    }
  }
  if (s.size() < 8) throw std::invalid_argument("IdentifySimplified: too few active samples");
  return s;
}

// Least squares for a few columns; returns the coefficients.
Eigen::VectorXd Lsq(const Eigen::MatrixXd& a, const Eigen::VectorXd& b) {
  return SolveTruncatedSvd(a, b).c;
}

double Rms(const ActiveSamples& s, const auto& gain) {
  double ss = 0.0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const double e = s.act[i] * gain(s.angle[i], s.vel[i]) - s.tau[i];
    ss += e * e;
  }
  return std::sqrt(ss / static_cast<double>(s.size()));
}

double Gaussian(const ParametricParams& p, double th) {
  const double s2 = 2.0 * p.ata_width_deg * p.ata_width_deg;
  return std::exp(-((th - p.ata_peak_deg) * (th - p.ata_peak_deg) -
                    (kReferenceAngleDeg - p.ata_peak_deg) * (kReferenceAngleDeg - p.ata_peak_deg)) /
                  s2);
}

double TwoSegment(const ParametricParams& p, double v) {
  return std::max(0.0, 1.0 + (v < 0.0 ? p.atv_slope_neg_per_deg_s : p.atv_slope_pos_per_deg_s) * v);
}

}  // namespace

ParametricParams FitParametricTorqueAngle(const PiecewiseLinear& torque_angle, double* rms_nm) {
  if (torque_angle.size() < 2) {
    throw std::invalid_argument("FitParametricTorqueAngle: need at least 2 breakpoints");
  }
  std::vector<double> th, y;
  for (double x = torque_angle.x().front(); x <= torque_angle.x().back() + 1e-9; x += 1.0) {
    th.push_back(DegToRad(x));
    y.push_back(torque_angle(x));
  }
  const Eigen::Index n = static_cast<Eigen::Index>(th.size());
  Eigen::VectorXd b = Eigen::Map<const Eigen::VectorXd>(y.data(), n);
  // Eq. 7.3 is linear in (mgl, k₁, offset) for fixed k₂: variable projection.
  const auto solve = [&](double k2, Eigen::VectorXd* c) {
    Eigen::MatrixXd a(n, 3);
    for (Eigen::Index i = 0; i < n; ++i) {
      a(i, 0) = std::sin(th[static_cast<std::size_t>(i)]);
      a(i, 1) = std::exp(k2 * th[static_cast<std::size_t>(i)]);
      a(i, 2) = 1.0;
    }
    const auto sol = SolveTruncatedSvd(a, b);
    if (c) *c = sol.c;
    return sol.rms;
  };
  double best_k = 0.0, best = std::numeric_limits<double>::infinity();
  for (double k = -12.0; k <= 12.0 + 1e-9; k += 0.25) {
    const double r = solve(k, nullptr);
    if (r < best) best = r, best_k = k;
  }
  double lo = best_k - 0.25, hi = best_k + 0.25;
  for (int it = 0; it < 40; ++it) {
    const double m1 = lo + (hi - lo) / 3.0, m2 = hi - (hi - lo) / 3.0;
    if (solve(m1, nullptr) < solve(m2, nullptr))
      hi = m2;
    else
      lo = m1;
  }
  const double k2 = solve(0.5 * (lo + hi), nullptr) < best ? 0.5 * (lo + hi) : best_k;
  Eigen::VectorXd c;
  const double rms = solve(k2, &c);
  if (rms_nm) *rms_nm = rms;
  ParametricParams p;
  p.mgl_nm = c(0);
  p.k1_nm = c(1);
  p.k2_per_rad = k2;
  p.offset_nm = c(2);
  return p;
}

SimplifiedResult IdentifySimplified(ModelKind kind, std::span<const TrialColumns> trials,
                                    const ParameterSet& base, const SimplifiedOptions& options) {
  SimplifiedResult res;
  res.params = base;
  res.params.model = kind;
  const std::string name(ModelKindName(kind));
  if (kind == ModelKind::kFull) {
    ActiveResult a = IdentifyActive(trials, base.passive, options.active);
    res.params.active = a.active;
    res.report = a.report;
    return res;
  }
  const ActiveSamples s = Collect(trials, base.passive, options.active,
                                  /*positive_only=*/kind == ModelKind::kParametric);
  const Eigen::Index n = static_cast<Eigen::Index>(s.size());
  ActiveParams& act = res.params.active;
  double rms = 0.0;

  if (kind == ModelKind::kTorqueGenerator) {  // §5.5.1: f_ata = f_atv = 1
    double ft = 0.0, ff = 0.0;
    for (std::size_t i = 0; i < s.size(); ++i) ft += s.act[i] * s.tau[i], ff += s.act[i] * s.act[i];
    act.torque_scale_nm = ft / ff;
    const double k = act.torque_scale_nm;
    rms = Rms(s, [&](double, double) { return k; });
  } else if (kind == ModelKind::kSingleSegment) {  // Eqs. 5.1–5.2
    double a = 0.0, b = 1.0, c = 0.0, d = 1.0;     // τ_scale absorbed in (a, b)
    const Eigen::VectorXd y = Eigen::Map<const Eigen::VectorXd>(s.tau.data(), n);
    // One half-step of the alternating fit: τ ≈ act·(p·x + q)·(slope·z +
    // offset) solved for (p, q) with the other line held fixed.
    const auto fit_line = [&](const std::vector<double>& x, const std::vector<double>& z,
                              double slope, double offset) {
      Eigen::MatrixXd m(n, 2);
      for (Eigen::Index i = 0; i < n; ++i) {
        const auto k = static_cast<std::size_t>(i);
        const double g = s.act[k] * (slope * z[k] + offset);
        m(i, 0) = g * x[k];
        m(i, 1) = g;
      }
      return Lsq(m, y);
    };
    for (int it = 0; it < options.iterations; ++it) {
      const Eigen::VectorXd ab = fit_line(s.angle, s.vel, c, d);
      a = ab(0), b = ab(1);
      const Eigen::VectorXd cd = fit_line(s.vel, s.angle, a, b);
      c = cd(0), d = cd(1);
    }
    const double ka = a * kReferenceAngleDeg + b;
    if (!(std::abs(ka) > 0.0) || !(std::abs(d) > 0.0)) {
      throw std::invalid_argument("IdentifySimplified(single_segment): degenerate fit");
    }
    res.params.single_segment = {a / ka, b / ka, c / d, 1.0};
    act.torque_scale_nm = ka * d;
    const SingleSegmentParams ss = res.params.single_segment;
    const double k = act.torque_scale_nm;
    rms = Rms(s, [&](double th, double v) {
      return k * std::max(0.0, ss.a * th + ss.b) * std::max(0.0, ss.c * v + ss.d);
    });
  } else if (kind == ModelKind::kStaticGainPwlVelocity) {  // §7.3
    const auto bp = ResolveBreakpoints(options.velocity, s.vel);
    const Eigen::Index mv = static_cast<Eigen::Index>(bp.size());
    Eigen::MatrixXd m = Eigen::MatrixXd::Zero(n, mv);
    Eigen::VectorXd y = Eigen::Map<const Eigen::VectorXd>(s.tau.data(), n);
    for (Eigen::Index i = 0; i < n; ++i) {
      SetPwlBasisRow(m, i, 0, bp, s.vel[static_cast<std::size_t>(i)],
                     s.act[static_cast<std::size_t>(i)]);
    }
    const Eigen::VectorXd c = SolveNonNegative(m, y);  // gains ≥ 0 (§3.4)
    const PiecewiseLinear curve(bp, std::vector<double>(c.data(), c.data() + mv));
    const double k = curve(kReferenceVelocityDegS);
    if (!(k > 0.0))
      throw std::invalid_argument("IdentifySimplified(static_gain): gain at 0 deg/s not positive");
    act.torque_scale_nm = k;
    act.torque_velocity = curve.Scaled(1.0 / k);
    act.torque_angle = PiecewiseLinear::Constant(1.0, kReferenceAngleDeg);
    rms = Rms(s, [&](double, double v) { return curve(v); });
  } else {  // kParametric, §7.4.4
    ParametricParams p;
    double pta_rms = 0.0;
    p = FitParametricTorqueAngle(base.passive.torque_angle, &pta_rms);
    res.report.fit_rms["parametric_tau_pta_nm"] = pta_rms;
    double scale = 1.0;
    for (int it = 0; it < options.iterations; ++it) {
      // Gaussian f_ata: log(τ/(f·f_atv)) = q0 + q1·θ + q2·θ².
      std::vector<Eigen::Index> rows;
      for (Eigen::Index i = 0; i < n; ++i) {
        if (TwoSegment(p, s.vel[static_cast<std::size_t>(i)]) > 1e-6) rows.push_back(i);
      }
      Eigen::MatrixXd m(static_cast<Eigen::Index>(rows.size()), 3);
      Eigen::VectorXd y(static_cast<Eigen::Index>(rows.size()));
      for (std::size_t r = 0; r < rows.size(); ++r) {
        const auto k = static_cast<std::size_t>(rows[r]);
        const double th = s.angle[k] - kReferenceAngleDeg;  // centred for conditioning
        m(static_cast<Eigen::Index>(r), 0) = 1.0;
        m(static_cast<Eigen::Index>(r), 1) = th;
        m(static_cast<Eigen::Index>(r), 2) = th * th;
        y(static_cast<Eigen::Index>(r)) = std::log(s.tau[k] / (s.act[k] * TwoSegment(p, s.vel[k])));
      }
      const Eigen::VectorXd q = Lsq(m, y);
      const double q2 = std::min(q(2), -1e-9);  // a bell, not a bowl
      p.ata_width_deg = std::sqrt(-1.0 / (2.0 * q2));
      p.ata_peak_deg = kReferenceAngleDeg - q(1) / (2.0 * q2);
      // Two-segment f_atv: τ/(f·f_ata) = S + S·s₋·min(θ̇, 0) + S·s₊·max(θ̇, 0).
      Eigen::MatrixXd m2(n, 3);
      Eigen::VectorXd y2(n);
      for (Eigen::Index i = 0; i < n; ++i) {
        const auto k = static_cast<std::size_t>(i);
        const double g = s.act[k] * Gaussian(p, s.angle[k]);
        m2(i, 0) = g;
        m2(i, 1) = g * std::min(s.vel[k], 0.0);
        m2(i, 2) = g * std::max(s.vel[k], 0.0);
        y2(i) = s.tau[k];
      }
      const Eigen::VectorXd w = Lsq(m2, y2);
      if (!(w(0) > 0.0))
        throw std::invalid_argument("IdentifySimplified(parametric): scale not positive");
      scale = w(0);
      p.atv_slope_neg_per_deg_s = w(1) / w(0);
      p.atv_slope_pos_per_deg_s = w(2) / w(0);
    }
    res.params.parametric = p;
    act.torque_scale_nm = scale;
    rms = Rms(s, [&](double th, double v) { return scale * Gaussian(p, th) * TwoSegment(p, v); });
  }
  res.report.fit_rms[name + "_nm"] = rms;
  res.report.values[name + "_samples"] = static_cast<double>(s.size());
  return res;
}

}  // namespace fesbench::model
