#include "model/identify_passive_only.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "model/extrapolate.h"
#include "model/identify_passive.h"
#include "model/identify_rapid.h"
#include "model/integrators.h"
#include "model/units.h"

namespace fesbench::model {

void MarkPassiveOnly(ParameterSet& params, bool irc_identified) {
  if (!irc_identified) {
    params.irc = PiecewiseLinear({0.0, 1.0}, {0.0, 0.0});  // no current activates
    params.provenance.irc_method = kNotIdentified;
  }
  params.provenance.active_method = kNotIdentified;
}

bool IsPassiveOnly(const ParameterSet& params) {
  return params.provenance.irc_method == kNotIdentified ||
         params.provenance.active_method == kNotIdentified;
}

std::size_t PendulumReleaseIndex(std::span<const double> t_s, std::span<const double> angle_deg,
                                 double departure_deg, double hold_deg, double min_hold_s) {
  if (t_s.size() != angle_deg.size()) {
    throw std::invalid_argument("PendulumReleaseIndex: t_s and angle_deg differ in length");
  }
  const std::size_t n = angle_deg.size();
  std::size_t held = 0;
  while (held < n && std::abs(angle_deg[held] - angle_deg.front()) <= hold_deg) ++held;
  if (held == n || t_s[held] - t_s.front() < min_hold_s) return 0;
  std::size_t i = held;
  while (i < n && std::abs(angle_deg[i] - angle_deg.front()) <= departure_deg) ++i;
  return i == n ? 0 : i;
}

TrialColumns TrialFromSample(const TrialColumns& tr, std::size_t from) {
  const std::size_t n = tr.size();
  TrialColumns out;
  for (std::vector<double> TrialColumns::*col :
       {&TrialColumns::t_s, &TrialColumns::stim_ma, &TrialColumns::angle_deg,
        &TrialColumns::velocity_deg_s, &TrialColumns::accel_deg_s2, &TrialColumns::torque_nm,
        &TrialColumns::activation, &TrialColumns::emg}) {
    const std::vector<double>& in = tr.*col;
    if (in.size() == n) (out.*col).assign(in.begin() + static_cast<std::ptrdiff_t>(from), in.end());
  }
  return out;
}

namespace {

// The parametric pendulum of EstimatePendulumInertia: Eq. 4.35 with Eq. 7.3's
// τ_pta (gravity of amplitude m·g·l) and a bilinear-plus-Coulomb τ_ptv.
struct PendulumForm {
  double mgl_nm = 0.0, lo_deg = 0.0, hi_deg = 0.0;  // fixed
  double inertia_kgm2 = 0.0, hang_deg = 0.0, offset_nm = 0.0;
  double ext_nm = 0.0, ext_width_deg = 8.0, flex_nm = 0.0, flex_width_deg = 8.0;
  double damping_pos = 0.0, damping_neg = 0.0, coulomb_nm = 0.0;

  // θ̈, deg/s², at (θ, θ̇) in deg and deg/s.
  double AccelDegS2(double angle_deg, double velocity_deg_s) const {
    const double pta = mgl_nm * std::sin(DegToRad(angle_deg - hang_deg)) + offset_nm -
                       ext_nm * std::exp(-(angle_deg - lo_deg) / ext_width_deg) +
                       flex_nm * std::exp((angle_deg - hi_deg) / flex_width_deg);
    const double ptv = damping_pos * std::max(velocity_deg_s, 0.0) +
                       damping_neg * std::min(velocity_deg_s, 0.0) +
                       coulomb_nm * std::tanh(velocity_deg_s / 5.0);
    return -RadToDeg((pta + ptv) / inertia_kgm2);
  }
};

// The unknowns of the output-error fit: J as its logarithm, the widths
// mapped onto kMinWidthDeg…kMaxWidthDeg (a logistic of the unknown): an end
// term narrower than a sample's travel or wider than half the range stops
// being an end term.
constexpr int kFormUnknowns = 10;
using FormVector = Eigen::Matrix<double, kFormUnknowns, 1>;
constexpr double kMinWidthDeg = 2.0, kMaxWidthDeg = 20.0;

double WidthOf(double z) {
  return kMinWidthDeg + (kMaxWidthDeg - kMinWidthDeg) / (1.0 + std::exp(-z));
}
double UnknownOfWidth(double w) {
  const double u = (w - kMinWidthDeg) / (kMaxWidthDeg - kMinWidthDeg);
  return std::log(u / (1.0 - u));
}

FormVector ToVector(const PendulumForm& f) {
  FormVector x;
  x << std::log(f.inertia_kgm2), f.hang_deg, f.offset_nm, f.ext_nm, UnknownOfWidth(f.ext_width_deg),
      f.flex_nm, UnknownOfWidth(f.flex_width_deg), f.damping_pos, f.damping_neg, f.coulomb_nm;
  return x;
}

PendulumForm FromVector(PendulumForm f, const FormVector& x) {
  f.inertia_kgm2 = std::exp(x(0));
  f.hang_deg = x(1);
  f.offset_nm = x(2);
  f.ext_nm = x(3);
  f.ext_width_deg = WidthOf(x(4));
  f.flex_nm = x(5);
  f.flex_width_deg = WidthOf(x(6));
  f.damping_pos = x(7);
  f.damping_neg = x(8);
  f.coulomb_nm = x(9);
  return f;
}

// A stretch of a swing without gaps: simulated from its first sample.
struct Stretch {
  std::vector<double> t_s, angle_deg, velocity_deg_s;
};

// The stretches of `swings` (split where a stop's contact was left out),
// each at least min_s long.
std::vector<Stretch> Stretches(std::span<const TrialColumns> swings, double min_s) {
  std::vector<Stretch> out;
  for (const TrialColumns& tr : swings) {
    if (tr.size() < 2) continue;
    const double max_step_s =
        1.5 * (tr.t_s.back() - tr.t_s.front()) / static_cast<double>(tr.size() - 1);
    std::size_t begin = 0;
    for (std::size_t i = 1; i <= tr.size(); ++i) {
      const bool gap = i == tr.size() || tr.t_s[i] - tr.t_s[i - 1] > max_step_s;
      if (!gap) continue;
      if (tr.t_s[i - 1] - tr.t_s[begin] >= min_s) {
        Stretch st;
        st.t_s.assign(tr.t_s.begin() + static_cast<std::ptrdiff_t>(begin),
                      tr.t_s.begin() + static_cast<std::ptrdiff_t>(i));
        st.angle_deg.assign(tr.angle_deg.begin() + static_cast<std::ptrdiff_t>(begin),
                            tr.angle_deg.begin() + static_cast<std::ptrdiff_t>(i));
        st.velocity_deg_s.assign(tr.velocity_deg_s.begin() + static_cast<std::ptrdiff_t>(begin),
                                 tr.velocity_deg_s.begin() + static_cast<std::ptrdiff_t>(i));
        out.push_back(std::move(st));
      }
      begin = i;
    }
  }
  return out;
}

// Simulated minus recorded angle at every sample of every stretch (RK4,
// model/integrators.h, steps of at most 2.5 ms between samples); a
// diverging simulation gives large finite residuals.
void OutputResiduals(const PendulumForm& f, std::span<const Stretch> stretches,
                     Eigen::VectorXd& r) {
  const auto rhs = [&f](double, const Eigen::Vector2d& x) {
    return Eigen::Vector2d(x(1), f.AccelDegS2(x(0), x(1)));
  };
  Eigen::Index k = 0;
  for (const Stretch& st : stretches) {
    Eigen::Vector2d x(st.angle_deg.front(), st.velocity_deg_s.front());
    r(k++) = 0.0;
    for (std::size_t i = 1; i < st.t_s.size(); ++i) {
      x = IntegrateRk4(rhs, st.t_s[i - 1], st.t_s[i], x, 2.5e-3);
      if (!std::isfinite(x(0)) || std::abs(x(0)) > 1e3) x(0) = 1e3;
      r(k++) = x(0) - st.angle_deg[i];
    }
  }
}

// Levenberg–Marquardt on the output error from `start` over the unknowns
// `free` (indices into FormVector; the others held), forward-difference
// Jacobian; returns the form and its residual sum of squares.
std::pair<PendulumForm, double> FitOutputError(const PendulumForm& start,
                                               std::span<const Stretch> stretches,
                                               Eigen::Index samples, std::span<const int> free,
                                               int iterations) {
  FormVector x = ToVector(start);
  Eigen::VectorXd r(samples), r_try(samples);
  OutputResiduals(start, stretches, r);
  double cost = r.squaredNorm();
  const Eigen::Index m = static_cast<Eigen::Index>(free.size());
  Eigen::MatrixXd jac(samples, m);
  double lambda = 1e-2;
  for (int it = 0; it < iterations; ++it) {
    for (Eigen::Index j = 0; j < m; ++j) {
      FormVector xj = x;
      const int k = free[static_cast<std::size_t>(j)];
      const double h = 1e-6 * std::max(1.0, std::abs(x(k)));
      xj(k) += h;
      OutputResiduals(FromVector(start, xj), stretches, r_try);
      jac.col(j) = (r_try - r) / h;
    }
    const Eigen::MatrixXd jtj = jac.transpose() * jac;
    const Eigen::VectorXd jtr = jac.transpose() * r;
    bool improved = false;
    for (int tries = 0; tries < 10 && !improved; ++tries) {
      Eigen::MatrixXd a = jtj;
      a.diagonal() += lambda * (jtj.diagonal().array() + 1e-12).matrix();
      const Eigen::VectorXd dx = a.ldlt().solve(-jtr);
      FormVector x_try = x;
      for (Eigen::Index j = 0; j < m; ++j) x_try(free[static_cast<std::size_t>(j)]) += dx(j);
      OutputResiduals(FromVector(start, x_try), stretches, r_try);
      const double c = r_try.squaredNorm();
      if (std::isfinite(c) && c < cost) {
        improved = true;
        const bool converged = cost - c < 1e-10 * cost;
        x = x_try, r = r_try, cost = c;
        lambda = std::max(lambda / 3.0, 1e-9);
        if (converged) return {FromVector(start, x), cost};
      } else {
        lambda *= 4.0;
      }
    }
    if (!improved) break;
  }
  return {FromVector(start, x), cost};
}

}  // namespace

PendulumInertia EstimatePendulumInertia(std::span<const TrialColumns> swings,
                                        double gravity_moment_nm) {
  constexpr const char* kWhat = "EstimatePendulumInertia";
  if (!(gravity_moment_nm > 0.0) || !std::isfinite(gravity_moment_nm)) {
    throw std::invalid_argument(std::string(kWhat) + ": gravity_moment_nm must be finite and > 0");
  }
  for (const TrialColumns& tr : swings) {
    const std::size_t n = tr.size();
    RequireColumn(kWhat, "t_s", tr.t_s, n);
    RequireColumn(kWhat, "angle_deg", tr.angle_deg, n);
    RequireColumn(kWhat, "velocity_deg_s", tr.velocity_deg_s, n);
  }
  const std::vector<Stretch> stretches = Stretches(swings, 0.5);
  double lo = INFINITY, hi = -INFINITY;
  Eigen::Index samples = 0;
  const Stretch* longest = nullptr;
  for (const Stretch& st : stretches) {
    for (double a : st.angle_deg) lo = std::min(lo, a), hi = std::max(hi, a);
    samples += static_cast<Eigen::Index>(st.t_s.size());
    if (!longest || st.t_s.size() > longest->t_s.size()) longest = &st;
  }
  if (!longest || hi - lo < 20.0) {
    throw std::invalid_argument(std::string(kWhat) +
                                ": the swings span under 20 deg (or last under 0.5 s); their "
                                "period cannot give J");
  }

  // The start: a pendulum hanging where the longest stretch comes to rest,
  // its period from the turning points (θ̇ = 0): J = m·g·l / ω².
  PendulumForm start;
  start.mgl_nm = gravity_moment_nm;
  start.lo_deg = lo;
  start.hi_deg = hi;
  start.hang_deg = longest->angle_deg.back();
  std::vector<double> turns;
  for (std::size_t i = 1; i < longest->t_s.size(); ++i) {
    const double v0 = longest->velocity_deg_s[i - 1], v1 = longest->velocity_deg_s[i];
    if (v0 * v1 < 0.0 && std::abs(longest->angle_deg[i] - start.hang_deg) > 1.0) {
      turns.push_back(longest->t_s[i]);
    }
  }
  if (turns.empty()) {
    throw std::invalid_argument(std::string(kWhat) +
                                ": the swing never turns back; its period cannot give J");
  }
  // One turn (a heavily damped knee): from the release, itself a turn.
  if (turns.size() == 1) turns.insert(turns.begin(), longest->t_s.front());
  const double half_period_s =
      (turns.back() - turns.front()) / static_cast<double>(turns.size() - 1);
  const double omega = kPi / half_period_s;
  start.inertia_kgm2 = gravity_moment_nm / (omega * omega);
  start.ext_nm = start.flex_nm = 0.1 * gravity_moment_nm;
  start.damping_pos = start.damping_neg = 1e-3;

  // The widths held at the start's first (the amplitudes settle), then free.
  constexpr std::array<int, 8> kWithoutWidths = {0, 1, 2, 3, 5, 7, 8, 9};
  constexpr std::array<int, 10> kAll = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9};
  const PendulumForm settled = FitOutputError(start, stretches, samples, kWithoutWidths, 30).first;
  const auto [form, cost] = FitOutputError(settled, stretches, samples, kAll, 60);
  if (!(form.hang_deg >= 0.0 && form.hang_deg <= 180.0)) {
    throw std::invalid_argument(
        std::string(kWhat) + ": the swings fit a shank hanging at " +
        std::to_string(static_cast<int>(std::lround(form.hang_deg))) +
        " deg, outside 0–180; is the knee angle flexion-negative? (fesbench's is "
        "flexion-positive, 0 = full extension)");
  }
  // J's profile: the fit again with J held kProfileFactor below and above,
  // every other unknown refitted, from two starts (the best form with J
  // alone changed, and with every torque but gravity's scaled with J: the
  // scale the swing cannot see), the better kept — one start can diverge
  // where the other does not (on a real recording, 883° against 2.6°).
  constexpr std::array<int, 9> kAllButJ = {1, 2, 3, 4, 5, 6, 7, 8, 9};
  std::array<double, 2> profile_rms{};
  for (int side = 0; side < 2; ++side) {
    const double f = side == 0 ? 1.0 / kProfileFactor : kProfileFactor;
    PendulumForm held = form;
    held.inertia_kgm2 *= f;
    PendulumForm scaled = held;
    for (double* torque : {&scaled.offset_nm, &scaled.ext_nm, &scaled.flex_nm, &scaled.damping_pos,
                           &scaled.damping_neg, &scaled.coulomb_nm}) {
      *torque *= f;
    }
    const double c = std::min(FitOutputError(held, stretches, samples, kAllButJ, 60).second,
                              FitOutputError(scaled, stretches, samples, kAllButJ, 60).second);
    profile_rms[static_cast<std::size_t>(side)] = std::sqrt(c / static_cast<double>(samples));
  }
  PendulumInertia out;
  out.inertia_kgm2 = form.inertia_kgm2;
  out.hang_deg = form.hang_deg;
  out.offset_nm = form.offset_nm;
  out.rms_deg = std::sqrt(cost / static_cast<double>(samples));
  out.profile_rms_low_deg = profile_rms[0];
  out.profile_rms_high_deg = profile_rms[1];
  out.determined = std::min(profile_rms[0], profile_rms[1]) >= kDeterminedRmsRatio * out.rms_deg;
  out.samples = static_cast<std::size_t>(samples);
  return out;
}

PassiveOnlyResult IdentifyPassiveOnly(std::span<const TrialColumns> trials,
                                      const PassiveOnlyOptions& options) {
  if (trials.empty()) throw std::invalid_argument("IdentifyPassiveOnly: no free-swing trials");
  const bool inertia_given = options.inertia_kgm2 > 0.0 && std::isfinite(options.inertia_kgm2);
  if (!inertia_given &&
      !(options.gravity_moment_nm > 0.0 && std::isfinite(options.gravity_moment_nm))) {
    throw std::invalid_argument(
        "IdentifyPassiveOnly: give inertia_kgm2 or gravity_moment_nm, finite and > 0");
  }

  // 0. Unstimulated swings only; 1. θ̇ and θ̈ over the whole recording (§5.1,
  //    so the release's are not edge values), then each from its release on,
  //    with a zero activation.
  std::vector<TrialColumns> swings;
  for (std::size_t k = 0; k < trials.size(); ++k) {
    TrialColumns full = trials[k];
    const std::size_t n = full.size();
    RequireColumn("IdentifyPassiveOnly", "angle_deg", full.angle_deg, n);
    if (full.stim_ma.empty()) full.stim_ma.assign(n, 0.0);
    RequireColumn("IdentifyPassiveOnly", "stim_ma", full.stim_ma, n);
    if (std::any_of(full.stim_ma.begin(), full.stim_ma.end(), [](double u) { return u != 0.0; })) {
      throw std::invalid_argument("IdentifyPassiveOnly: trial " + std::to_string(k) +
                                  " is stimulated; only unstimulated swings are passive");
    }
    if (full.velocity_deg_s.size() != n || full.accel_deg_s2.size() != n) AddKinematics(full);
    full.activation.assign(n, 0.0);
    swings.push_back(TrialFromSample(full, PendulumReleaseIndex(full.t_s, full.angle_deg)));
  }

  // 2. Eq. 4.35 with J known (§7.4.1), away from a bench's stops.
  PassiveOnlyResult out;
  ParameterSet& ps = out.parameters;
  ps = ExampleParameterSet();
  ps.model = ModelKind::kFull;
  double lo = INFINITY, hi = -INFINITY, vlo = INFINITY, vhi = -INFINITY;
  std::size_t samples = 0;
  std::vector<TrialColumns> free;
  for (const TrialColumns& tr : swings) {
    free.push_back(options.joint_limits
                       ? WithoutStopContact(tr, *options.joint_limits, options.stop_margin_deg,
                                            options.stop_guard_s)
                       : tr);
    const TrialColumns& f = free.back();
    for (std::size_t i = 0; i < f.size(); ++i) {
      lo = std::min(lo, f.angle_deg[i]);
      hi = std::max(hi, f.angle_deg[i]);
      vlo = std::min(vlo, f.velocity_deg_s[i]);
      vhi = std::max(vhi, f.velocity_deg_s[i]);
    }
    samples += f.size();
  }
  // 1a. J from the swings' period with gravity's amplitude fixed.
  double inertia = options.inertia_kgm2;
  if (!inertia_given) {
    const PendulumInertia est = EstimatePendulumInertia(free, options.gravity_moment_nm);
    out.report.fit_rms["pendulum_inertia_deg"] = est.rms_deg;
    out.report.values["pendulum_inertia_kgm2"] = est.inertia_kgm2;
    out.report.values["pendulum_hang_deg"] = est.hang_deg;
    out.report.values["pendulum_profile_low_deg"] = est.profile_rms_low_deg;
    out.report.values["pendulum_profile_high_deg"] = est.profile_rms_high_deg;
    out.report.values["pendulum_inertia_determined"] = est.determined ? 1.0 : 0.0;
    char figures[200];
    std::snprintf(figures, sizeof figures,
                  "J %.3g kg·m² fits them to %.3g deg, J ×%.2f and ×%.2f to %.3g and %.3g deg",
                  est.inertia_kgm2, est.rms_deg, 1.0 / kProfileFactor, kProfileFactor,
                  est.profile_rms_low_deg, est.profile_rms_high_deg);
    if (est.determined) {
      inertia = est.inertia_kgm2;
      out.inertia_source = InertiaSource::kSwings;
    } else if (options.fallback_inertia_kgm2 > 0.0) {
      inertia = options.fallback_inertia_kgm2;
      out.inertia_source = InertiaSource::kFallback;
      out.report.warnings.push_back(
          std::string("J not determined by the swings (") + figures +
          "): the tissue's stiffness mid-range passes for gravity's; J taken from the fallback");
    } else {
      throw std::invalid_argument(
          std::string("IdentifyPassiveOnly: J is not determined by the swings (") + figures +
          "); give inertia_kgm2, or the body measures for Eq. 4.13's");
    }
  }
  const PassiveResult pas =
      IdentifyPassiveKnownInertia(free, inertia, options.angle, options.velocity,
                                  /*max_activation=*/0.5, options.relative_tolerance);
  ps.passive = pas.passive;
  out.report.Merge(pas.report);
  out.report.values["passive_only_samples"] = static_cast<double>(samples);

  Provenance& prov = ps.provenance;
  prov = {};
  prov.identified_range_deg["tau_pta"] = {lo, hi};
  prov.identified_range_deg_s["tau_ptv"] = {vlo, vhi};

  // 3. Beyond the visited angles and speeds (model/extrapolate.h), §6.5 reference.
  if (hi - lo >= 5.0) {
    const PassiveAngleForm form =
        FitPassiveAngleForm(ps.passive.torque_angle, lo, hi, options.gravity_moment_nm);
    ps.passive.torque_angle =
        ExtendPassiveAngle(ps.passive.torque_angle, form, lo - options.extend_angle_deg,
                           hi + options.extend_angle_deg);
    out.report.fit_rms["tau_pta_form_nm"] = form.rms_nm;
    out.report.values["tau_pta_form_mgl_nm"] = form.mgl_nm();
    out.report.values["tau_pta_form_hang_deg"] = form.hang_deg();
  }
  const double vmax = options.extend_velocity_deg_s;
  ps.passive.torque_velocity =
      ExtendVelocityCurve(ps.passive.torque_velocity, vlo, vhi, -vmax, vmax, true);
  ps.passive = ReferencePassive(ps.passive);

  // 4. Output error on the knee angle (the active block has nothing to act
  //    on: with zero activation its ordinates stay at their start).
  if (options.refine_iterations > 0) {
    OutputErrorOptions oe;
    oe.iterations = options.refine_iterations;
    oe.prior_weight = options.refine_prior_weight;
    oe.joint_limits = options.joint_limits;
    const Provenance keep = prov;
    const OutputErrorResult refined = RefineOutputError(ps, swings, oe);
    ps = refined.parameters;
    ps.provenance = keep;
    out.report.Merge(refined.report);
  }

  prov.passive_method = "free_swing_known_inertia";
  MarkPassiveOnly(ps, /*irc_identified=*/false);
  prov.fit_rms = out.report.fit_rms;
  prov.warnings = out.report.warnings;
  return out;
}

}  // namespace fesbench::model
