#include "model/identify_rapid.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "model/conditioning.h"
#include "model/contraction.h"
#include "model/extrapolate.h"
#include "model/identify_least_squares.h"
#include "model/joint_model.h"
#include "model/simulate.h"
#include "model/units.h"

namespace fesbench::model {

namespace {

// The refined ordinates of a parameter set, in a fixed order: τ_pta, τ_ptv,
// f_ata, f_atv, ln τ_scale.
std::vector<double> PackCurves(const ParameterSet& p) {
  std::vector<double> v;
  for (const PiecewiseLinear* c : {&p.passive.torque_angle, &p.passive.torque_velocity,
                                   &p.active.torque_angle, &p.active.torque_velocity}) {
    v.insert(v.end(), c->y().begin(), c->y().end());
  }
  v.push_back(std::log(p.active.torque_scale_nm));
  return v;
}

ParameterSet UnpackCurves(ParameterSet p, const Eigen::VectorXd& v) {
  Eigen::Index k = 0;
  for (PiecewiseLinear* c : {&p.passive.torque_angle, &p.passive.torque_velocity,
                             &p.active.torque_angle, &p.active.torque_velocity}) {
    std::vector<double> y(v.data() + k, v.data() + k + static_cast<Eigen::Index>(c->size()));
    k += static_cast<Eigen::Index>(c->size());
    *c = PiecewiseLinear(c->x(), std::move(y));
  }
  p.active.torque_scale_nm = std::exp(v(k));
  return p;
}

// Projects the f_ata and f_atv ordinates of a packed vector (PackCurves) onto
// gains ≥ 0: a muscle only pulls (§3.4), and a negative gain would not make a
// valid parameter set.
void ClampActiveGains(const ParameterSet& p, Eigen::VectorXd& v) {
  const auto begin =
      static_cast<Eigen::Index>(p.passive.torque_angle.size() + p.passive.torque_velocity.size());
  const auto end = begin + static_cast<Eigen::Index>(p.active.torque_angle.size() +
                                                     p.active.torque_velocity.size());
  for (Eigen::Index i = begin; i < end; ++i) v(i) = std::max(v(i), 0.0);
}

// A piecewise-linear curve at x as the simulator's tables evaluate it
// (JointModel: end values held at and beyond the end breakpoints): the
// basis weights of Eq. 4.30 (∂y/∂c_j), the value and the slope dy/dx.
struct CurvePoint {
  BasisWeights basis;
  double value = 0.0;
  double slope = 0.0;
};

CurvePoint At(const PiecewiseLinear& curve, double x) {
  const std::vector<double>& xs = curve.x();
  const std::vector<double>& ys = curve.y();
  const std::size_t m = xs.size();
  if (m == 1 || x <= xs.front()) return {{0, 1.0, 0.0}, ys.front(), 0.0};
  if (x >= xs.back()) return {{m - 2, 0.0, 1.0}, ys.back(), 0.0};
  const BasisWeights b = curve.Basis(x);
  const std::size_t lo = b.index_lo;
  return {b, b.weight_lo * ys[lo] + b.weight_hi * ys[lo + 1],
          (ys[lo + 1] - ys[lo]) / (xs[lo + 1] - xs[lo])};
}

// The state (θ, θ̇) of a simulation and its sensitivities to a run of c
// packed parameters x_j (PackCurves): (θ, θ̇, ∂θ/∂x_1 … ∂θ/∂x_c,
// ∂θ̇/∂x_1 … ∂θ̇/∂x_c). Fixed capacity: the RK4 stages' temporaries live on
// the stack; more parameters than fit are taken in several passes.
constexpr Eigen::Index kTangentParameters = 63;
using Tangent =
    Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, 2 + 2 * kTangentParameters, 1>;

// Simulated minus measured knee angle of every trial (every stride-th
// sample), followed by the prior rows w·(x − x0)/scale. A diverging
// simulation gives non-finite residuals.
class OutputError {
 public:
  OutputError(const ParameterSet& start, std::span<const TrialColumns> trials,
              const OutputErrorOptions& options)
      : start_(start), trials_(trials), options_(options), x0_(PackCurves(start)) {
    for (const TrialColumns& tr : trials_) {
      pulses_.push_back(TrialPulses(tr, options.pulse_rate_hz));
      for (std::size_t i = 0; i < tr.size(); i += static_cast<std::size_t>(options.stride)) ++n_;
    }
    const auto add = [&](std::size_t count, double s) { scale_.insert(scale_.end(), count, s); };
    add(start.passive.torque_angle.size(), options.passive_torque_scale_nm);
    add(start.passive.torque_velocity.size(), options.passive_velocity_scale_nm);
    add(start.active.torque_angle.size(), options.active_gain_scale);
    add(start.active.torque_velocity.size(), options.active_gain_scale);
    add(1, options.log_torque_scale);
    prior_ = std::sqrt(options.prior_weight * static_cast<double>(n_));
  }

  Eigen::Index samples() const { return static_cast<Eigen::Index>(n_); }
  Eigen::VectorXd start() const { return Eigen::Map<const Eigen::VectorXd>(x0_.data(), size()); }
  Eigen::Index size() const { return static_cast<Eigen::Index>(x0_.size()); }

  Eigen::VectorXd operator()(const Eigen::VectorXd& x) const {
    Eigen::VectorXd r(samples() + size());
    const ParameterSet p = UnpackCurves(start_, x);
    Eigen::Index row = 0;
    for (std::size_t k = 0; k < trials_.size(); ++k) {
      const TrialColumns& tr = trials_[k];
      const SimulationResult sim = SimulateFreeSwing(p, pulses_[k], Options(k));
      for (std::size_t i = 0; i < tr.size(); i += static_cast<std::size_t>(options_.stride)) {
        r(row++) = i < sim.angle_deg.size() ? sim.angle_deg[i] - tr.angle_deg[i]
                                            : std::numeric_limits<double>::quiet_NaN();
      }
    }
    for (Eigen::Index j = 0; j < size(); ++j) {
      r(row++) =
          prior_ * (x(j) - x0_[static_cast<std::size_t>(j)]) / scale_[static_cast<std::size_t>(j)];
    }
    return r;
  }

  // The Jacobian of operator() at x into jac (rows × size(), allocated by
  // the caller): the angle rows from the sensitivity equations carried
  // through every RK4 stage of the simulation, i.e. the derivative of the
  // discrete map SimulateFreeSwing computes (as the free-swing J fit does,
  // identify_passive.cc), not a difference quotient; the prior rows are
  // diagonal. Rows of samples the simulation does not reach are NaN.
  void Jacobian(const Eigen::VectorXd& x, Eigen::MatrixXd& jac) const {
    const ParameterSet p = UnpackCurves(start_, x);
    const JointModel model = JointModel::FromParameters(p, ModelKind::kFull);
    jac.setZero();
    jac.topRows(samples()).setConstant(std::numeric_limits<double>::quiet_NaN());
    Eigen::Index row = 0;
    for (std::size_t k = 0; k < trials_.size(); ++k) {
      for (Eigen::Index first = 0; first < size(); first += kTangentParameters) {
        const Eigen::Index count = std::min(kTangentParameters, size() - first);
        Sensitivities(p, model, k, first, count, row, jac);
      }
      const auto stride = static_cast<std::size_t>(options_.stride);
      row += static_cast<Eigen::Index>((trials_[k].size() + stride - 1) / stride);
    }
    for (Eigen::Index j = 0; j < size(); ++j) {
      jac(row + j, j) = prior_ / scale_[static_cast<std::size_t>(j)];
    }
  }

  double AngleRms(const Eigen::VectorXd& r) const {
    return std::sqrt(r.head(samples()).squaredNorm() / static_cast<double>(n_));
  }

 private:
  SimulationOptions Options(std::size_t k) const {
    const TrialColumns& tr = trials_[k];
    SimulationOptions o;
    o.step_s = options_.step_s;
    o.pulse_rate_hz = options_.pulse_rate_hz;
    o.initial_angle_deg = tr.angle_deg.front();
    o.initial_velocity_deg_s = tr.velocity_deg_s.front();
    o.duration_s = tr.t_s.back() - tr.t_s.front() + 1.0 / tr.SampleRateHz();
    o.output_rate_hz = tr.SampleRateHz();
    o.joint_limits = options_.joint_limits;
    if (o.joint_limits) {
      o.initial_angle_deg = std::clamp(o.initial_angle_deg, o.joint_limits->min_angle_deg,
                                       o.joint_limits->max_angle_deg);
    }
    return o;
  }

  // Trial k simulated as SimulateFreeSwing does (the same RunPulseDriven,
  // RK4 stages and stops; SimulateFreeSwing associates each stage's
  // velocity update differently, the same values up to rounding), with the
  // sensitivities to the parameters
  // first … first + count − 1: their angle rows, from `row` on, into the
  // columns first … of jac. The equation of motion (JointModel, Eq. 3.16)
  //   θ̈ = −k·(τ_pta(θ) + τ_ptv(θ̇) + f_stim·τ_scale·f_ata⁺(θ)·f_atv⁺(θ̇)),
  // k = (180/π)/J, is linear in each curve's ordinates through the basis
  // weights of Eq. 4.30 (the gains clamped at 0: no sensitivity where
  // clamped), and the packed ln τ_scale enters as τ_scale·∂/∂τ_scale.
  void Sensitivities(const ParameterSet& p, const JointModel& model, std::size_t k,
                     Eigen::Index first, Eigen::Index count, Eigen::Index row,
                     Eigen::MatrixXd& jac) const {
    const TrialColumns& tr = trials_[k];
    const SimulationOptions o = Options(k);
    const std::size_t n_out = detail::ValidateOptions(o, detail::DefaultDuration(pulses_[k]));
    const PiecewiseLinear& pta = p.passive.torque_angle;
    const PiecewiseLinear& ptv = p.passive.torque_velocity;
    const PiecewiseLinear& ata = p.active.torque_angle;
    const PiecewiseLinear& atv = p.active.torque_velocity;
    const auto off_ptv = static_cast<Eigen::Index>(pta.size());
    const auto off_ata = off_ptv + static_cast<Eigen::Index>(ptv.size());
    const auto off_atv = off_ata + static_cast<Eigen::Index>(ata.size());
    const Eigen::Index log_scale = off_atv + static_cast<Eigen::Index>(atv.size());
    const double kk = RadToDeg(1.0 / p.passive.inertia_kgm2);
    const double scale = p.active.torque_scale_nm;
    JointModel::Segments segments;
    const auto rhs = [&](double /*t*/, const Tangent& x, double activation) {
      const double th = x[0], om = x[1];
      Tangent d(x.size());
      d[0] = om;
      d[1] = model.AccelerationDegS2(th, om, activation, segments);
      const CurvePoint cpta = At(pta, th), cptv = At(ptv, om);
      const CurvePoint cata = At(ata, th), catv = At(atv, om);
      const double act = activation * scale;
      const double ga = cata.value > 0.0 ? cata.value : 0.0;
      const double gv = catv.value > 0.0 ? catv.value : 0.0;
      const double on_a = cata.value > 0.0 ? 1.0 : 0.0, on_v = catv.value > 0.0 ? 1.0 : 0.0;
      // ∂θ̈/∂θ, ∂θ̈/∂θ̇ (the variational equation) …
      const double d_th = -kk * (cpta.slope + act * on_a * cata.slope * gv);
      const double d_om = -kk * (cptv.slope + act * ga * on_v * catv.slope);
      d.segment(2, count) = x.tail(count);
      d.tail(count) = d_th * x.segment(2, count) + d_om * x.tail(count);
      // … plus ∂θ̈/∂x_j, non-zero for two ordinates of each curve and ln τ_scale.
      const auto force = [&](Eigen::Index j, double v) {
        if (j >= first && j < first + count) d[2 + count + j - first] += v;
      };
      const auto curve = [&](Eigen::Index offset, const BasisWeights& b, double v) {
        const auto lo = offset + static_cast<Eigen::Index>(b.index_lo);
        if (b.weight_lo != 0.0) force(lo, v * b.weight_lo);
        if (b.weight_hi != 0.0) force(lo + 1, v * b.weight_hi);
      };
      curve(0, cpta.basis, -kk);
      curve(off_ptv, cptv.basis, -kk);
      curve(off_ata, cata.basis, -kk * act * on_a * gv);
      curve(off_atv, catv.basis, -kk * act * ga * on_v);
      force(log_scale, -kk * act * ga * gv);
      return d;
    };
    const auto record = [&](std::size_t i, double /*t*/, const Tangent& x, double /*a*/) {
      const auto stride = static_cast<std::size_t>(options_.stride);
      if (i >= tr.size() || i % stride != 0) return;
      jac.row(row + static_cast<Eigen::Index>(i / stride)).segment(first, count) =
          x.segment(2, count).transpose();
    };
    // The stops of SimulateFreeSwing: a clamped coordinate no longer
    // depends on the parameters.
    const std::optional<JointLimits>& limits = o.joint_limits;
    const auto stop = [&limits, count](Tangent& x) {
      if (!limits) return false;
      const auto hold = [&](double at, bool below) {
        x[0] = at;
        x.segment(2, count).setZero();
        if (below ? x[1] < 0.0 : x[1] > 0.0) {
          x[1] = 0.0;
          x.tail(count).setZero();
        }
        return true;
      };
      if (x[0] < limits->min_angle_deg || (x[0] == limits->min_angle_deg && x[1] < 0.0)) {
        return hold(limits->min_angle_deg, true);
      }
      if (x[0] > limits->max_angle_deg || (x[0] == limits->max_angle_deg && x[1] > 0.0)) {
        return hold(limits->max_angle_deg, false);
      }
      return false;
    };
    Tangent x0 = Tangent::Zero(2 + 2 * count);
    x0[0] = o.initial_angle_deg;
    x0[1] = o.initial_velocity_deg_s;
    const IntegratorSettings settings{IntegratorKind::kRk4, o.step_s, o.tolerances};
    IntegratorWorkspace ws;
    detail::RunPulseDriven(rhs, record, x0, p.contraction, p.irc, pulses_[k], o.pulse_rate_hz,
                           o.output_rate_hz, n_out, settings, ws, stop);
  }

  const ParameterSet& start_;
  std::span<const TrialColumns> trials_;
  OutputErrorOptions options_;
  std::vector<double> x0_;
  std::vector<double> scale_;
  std::vector<PulseTrain> pulses_;
  std::size_t n_ = 0;
  double prior_ = 0.0;
};

double Cost(const Eigen::VectorXd& r) {
  return r.allFinite() ? r.squaredNorm() : std::numeric_limits<double>::infinity();
}

}  // namespace

OutputErrorResult RefineOutputError(const ParameterSet& start, std::span<const TrialColumns> trials,
                                    const OutputErrorOptions& options) {
  const char* what = "RefineOutputError";
  if (trials.empty()) throw std::invalid_argument(std::string(what) + ": no trials");
  if (options.iterations < 0 || options.stride < 1 || !(options.step_s > 0.0) ||
      !(options.pulse_rate_hz > 0.0) || !(options.prior_weight >= 0.0) ||
      !(options.passive_torque_scale_nm > 0.0) || !(options.passive_velocity_scale_nm > 0.0) ||
      !(options.active_gain_scale > 0.0) || !(options.log_torque_scale > 0.0)) {
    throw std::invalid_argument(std::string(what) + ": an option is out of range");
  }
  if (start.passive.torque_angle.empty() || start.passive.torque_velocity.empty() ||
      start.active.torque_angle.empty() || start.active.torque_velocity.empty() ||
      !(start.active.torque_scale_nm > 0.0)) {
    throw std::invalid_argument(std::string(what) +
                                ": start needs passive and active curves and τ_scale > 0");
  }
  for (const TrialColumns& tr : trials) {
    const std::size_t n = tr.t_s.size();
    if (n < 2) throw std::invalid_argument(std::string(what) + ": a trial has < 2 samples");
    RequireColumn(what, "stim_ma", tr.stim_ma, n);
    RequireColumn(what, "angle_deg", tr.angle_deg, n);
    RequireColumn(what, "velocity_deg_s", tr.velocity_deg_s, n);
  }
  const OutputError error(start, trials, options);
  Eigen::VectorXd x = error.start();
  Eigen::VectorXd r = error(x);
  double cost = Cost(r);
  OutputErrorResult out;
  out.report.fit_rms["output_error_start_deg"] = error.AngleRms(r);
  // Levenberg–Marquardt (Marquardt's diagonal scaling), the Jacobian from
  // the sensitivity equations (OutputError::Jacobian); a step is kept only
  // if it lowers the cost. The matrices are allocated once.
  double lambda = 1e-2;
  int done = 0;
  Eigen::MatrixXd jac(r.size(), x.size()), jtj(x.size(), x.size()), a(x.size(), x.size());
  Eigen::VectorXd g(x.size()), xn(x.size());
  for (int it = 0; it < options.iterations && std::isfinite(cost); ++it) {
    error.Jacobian(x, jac);
    if (!jac.allFinite()) break;
    // JᵀJ's lower triangle only (a symmetric rank update, half the
    // product): the LDLT below reads no more.
    jtj.setZero();
    jtj.selfadjointView<Eigen::Lower>().rankUpdate(jac.transpose());
    g.noalias() = jac.transpose() * r;
    const double floor = std::max(jtj.diagonal().maxCoeff(), 1e-12);
    bool improved = false;
    for (int tries = 0; tries < 6 && !improved; ++tries) {
      a = jtj;
      // The floor keeps ordinates the trials never move (no support) fixed.
      a.diagonal() += lambda * (jtj.diagonal().array() + 1e-6 * floor).matrix();
      xn = x + a.ldlt().solve(-g);
      ClampActiveGains(start, xn);  // projected step
      Eigen::VectorXd rn = error(xn);
      const double cn = Cost(rn);
      if (cn < cost) {
        x = xn;
        r = std::move(rn);
        cost = cn;
        lambda *= 0.3;
        improved = true;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) break;
    ++done;
  }
  ParameterSet p = UnpackCurves(start, x);
  if (!(p.active.torque_angle(kReferenceAngleDeg) > 0.0) ||
      !(p.active.torque_velocity(0.0) > 0.0)) {
    // Not normalisable (§6.7): keep the start.
    p = start;
    r = error(error.start());
    done = 0;
    out.report.warnings.push_back(
        "output-error refinement left f_ata(90°) or f_atv(0) ≤ 0; "
        "kept the linear estimates");
  }
  p.passive = ReferencePassive(p.passive);  // §6.5
  p.active = NormaliseActive(p.active);     // §6.7
  out.parameters = std::move(p);
  out.report.fit_rms["output_error_deg"] = error.AngleRms(r);
  out.report.values["output_error_iterations"] = done;
  return out;
}

TrialColumns WithoutStopContact(const TrialColumns& tr, const JointLimits& stops, double margin_deg,
                                double guard_s) {
  const std::size_t n = tr.size();
  std::vector<bool> drop(n, false);
  for (std::size_t i = 0; i < n; ++i) {
    if (tr.angle_deg[i] > stops.min_angle_deg + margin_deg &&
        tr.angle_deg[i] < stops.max_angle_deg - margin_deg) {
      continue;
    }
    for (std::size_t j = i; j-- > 0 && tr.t_s[i] - tr.t_s[j] <= guard_s;) drop[j] = true;
    for (std::size_t j = i; j < n && tr.t_s[j] - tr.t_s[i] <= guard_s; ++j) drop[j] = true;
  }
  TrialColumns out;
  for (std::vector<double> TrialColumns::*col :
       {&TrialColumns::t_s, &TrialColumns::stim_ma, &TrialColumns::angle_deg,
        &TrialColumns::velocity_deg_s, &TrialColumns::accel_deg_s2, &TrialColumns::torque_nm,
        &TrialColumns::activation, &TrialColumns::emg}) {
    const std::vector<double>& in = tr.*col;
    if (in.size() != n) continue;
    for (std::size_t i = 0; i < n; ++i) {
      if (!drop[i]) (out.*col).push_back(in[i]);
    }
  }
  return out;
}

namespace {

CurveRange RangeOf(const std::vector<double>& v) {
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  return {*lo, *hi};
}

}  // namespace

RapidResult IdentifyRapid(const TrialColumns& isometric, const TrialColumns& passive,
                          const TrialColumns& active, const RapidOptions& options) {
  const TrialColumns swings[] = {passive, active};
  return IdentifyRapid(isometric, swings, options);
}

ReleaseInertia InertiaFromReleases(std::span<const TrialColumns> swings,
                                   std::span<const RapidTrials::Release> releases,
                                   double window_s, double max_travel_deg,
                                   double min_window_s) {
  const char* what = "InertiaFromReleases";
  if (releases.size() < 2) throw std::invalid_argument(std::string(what) + ": needs 2 releases");
  ReleaseInertia out;
  for (const RapidTrials::Release& r : releases) {
    const TrialColumns& h = r.hold;
    const std::size_t nh = h.t_s.size();
    RequireColumn(what, "torque_nm", h.torque_nm, nh);
    if (nh < 4) throw std::invalid_argument(std::string(what) + ": a hold has under 4 samples");
    double tq = 0.0;
    for (std::size_t i = nh / 2; i < nh; ++i) tq += h.torque_nm[i];
    out.hold_torque_nm.push_back(tq / static_cast<double>(nh - nh / 2));
    if (r.swing >= swings.size()) throw std::invalid_argument(std::string(what) + ": no such swing");
    const TrialColumns& sw = swings[r.swing];
    RequireColumn(what, "angle_deg", sw.angle_deg, sw.t_s.size());
    // The window: to the first sample max_travel_deg from the release
    // angle, within [min_window_s, window_s].
    double window = window_s;
    for (std::size_t i = 0; i < sw.t_s.size(); ++i) {
      if (std::abs(sw.angle_deg[i] - sw.angle_deg.front()) > max_travel_deg) {
        window = std::min(window_s, std::max(min_window_s, sw.t_s[i] - sw.t_s.front()));
        break;
      }
    }
    out.window_s.push_back(window);
    std::size_t n = 0;
    while (n < sw.t_s.size() && sw.t_s[n] - sw.t_s.front() <= window + 1e-9) ++n;
    if (n < 6) throw std::invalid_argument(std::string(what) + ": a swing is shorter than the window");
    // θ = c0 + c1·τ + c2·τ²/2 + c3·τ³/6, τ from the first sample.
    Eigen::MatrixXd a(static_cast<Eigen::Index>(n), 4);
    Eigen::VectorXd b(static_cast<Eigen::Index>(n));
    for (std::size_t i = 0; i < n; ++i) {
      const double t = sw.t_s[i] - sw.t_s.front();
      const auto k = static_cast<Eigen::Index>(i);
      a(k, 0) = 1.0;
      a(k, 1) = t;
      a(k, 2) = 0.5 * t * t;
      a(k, 3) = t * t * t / 6.0;
      b(k) = sw.angle_deg[i];
    }
    const Eigen::VectorXd c = a.colPivHouseholderQr().solve(b);
    out.accel_deg_s2.push_back(c(2));
  }
  // τ_hold = c − J·θ̈₀ (θ̈₀ in rad/s²).
  const std::size_t n = releases.size();
  double mx = 0.0, my = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    mx += -DegToRad(out.accel_deg_s2[i]) / static_cast<double>(n);
    my += out.hold_torque_nm[i] / static_cast<double>(n);
  }
  double sxx = 0.0, sxy = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = -DegToRad(out.accel_deg_s2[i]) - mx;
    sxx += x * x;
    sxy += x * (out.hold_torque_nm[i] - my);
  }
  if (!(sxx > 1e-12)) throw std::invalid_argument(std::string(what) + ": the releases do not differ");
  out.inertia_kgm2 = sxy / sxx;
  double ss = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double e = out.hold_torque_nm[i] - (my + out.inertia_kgm2 * (-DegToRad(out.accel_deg_s2[i]) - mx));
    ss += e * e;
  }
  out.rms_nm = std::sqrt(ss / static_cast<double>(n));
  return out;
}

ParameterSet ScaleTorques(const ParameterSet& p, double scale) {
  ParameterSet out = p;
  out.passive.inertia_kgm2 *= scale;
  out.passive.torque_angle = p.passive.torque_angle.Scaled(scale);
  out.passive.torque_velocity = p.passive.torque_velocity.Scaled(scale);
  out.active.torque_scale_nm *= scale;
  return out;
}

RapidResult IdentifyRapid(const TrialColumns& isometric, std::span<const TrialColumns> swings_in,
                          const RapidOptions& options) {
  RapidTrials trials;
  trials.isometric = isometric;
  trials.swings.assign(swings_in.begin(), swings_in.end());
  return IdentifyRapid(trials, options);
}

RapidResult IdentifyRapid(const RapidTrials& trials, const RapidOptions& options) {
  const TrialColumns& isometric = trials.isometric;
  const std::span<const TrialColumns> swings_in = trials.swings;
  if (!(options.inertia_kgm2 > 0.0) || !std::isfinite(options.inertia_kgm2)) {
    throw std::invalid_argument("IdentifyRapid: inertia_kgm2 must be finite and > 0");
  }
  if (swings_in.empty()) throw std::invalid_argument("IdentifyRapid: no free-swing trials");
  RapidResult out;
  ParameterSet& ps = out.parameters;
  ps.model = ModelKind::kFull;

  // 1. Contraction dynamics from the averaged impulses (§4.1, Eqs. 4.2/4.4)
  //    and the IRC by deconvolving the ramp with them (§4.1.3, Eqs. 4.6–4.8).
  const TrialColumns iso[] = {isometric};
  const ContractionResult contraction = IdentifyContraction(iso, options.contraction);
  ps.contraction = contraction.contraction;
  out.report.Merge(contraction.report);
  IrcOptions irc_options = options.irc;
  irc_options.ideal = ps.contraction;
  const IrcResult irc = IdentifyIrc(kRapidIrcMethod, isometric, irc_options);
  ps.irc = irc.irc;
  out.report.Merge(irc.report);
  if (options.threshold_ma) {
    ps.irc = WithOnsetAtThreshold(ps.irc, *options.threshold_ma);
    out.report.values["irc_onset_ma"] = *options.threshold_ma;
  }
  out.report.values["irc_torque_scale_nm"] = irc.torque_scale_nm;

  // 2. Kinematics and activation of the free-swing trials; the samples the
  //    equation-error fits use (stop contact left out).
  std::vector<TrialColumns> swing(swings_in.begin(), swings_in.end());
  std::vector<TrialColumns> fit;
  for (TrialColumns& tr : swing) {
    AddKinematics(tr);
    std::vector<double> t(tr.t_s.size());
    for (std::size_t i = 0; i < t.size(); ++i) t[i] = tr.t_s[i] - tr.t_s.front();
    tr.activation = ActivationAt(ps.contraction, ps.irc, TrialPulses(tr, options.pulse_rate_hz),
                                 options.pulse_rate_hz, t);
    fit.push_back(options.joint_limits
                      ? WithoutStopContact(tr, *options.joint_limits, options.stop_margin_deg,
                                           options.stop_guard_s)
                      : tr);
  }

  // 3. Passive with known inertia (§7.4.1), then active (Eq. 4.40).
  const PassiveResult pas = IdentifyPassiveKnownInertia(
      fit, options.inertia_kgm2, options.passive_angle, options.passive_velocity,
      options.max_passive_activation, options.relative_tolerance);
  ps.passive = pas.passive;
  out.report.Merge(pas.report);
  ActiveOptions ao;
  ao.angle = options.active_angle;
  ao.velocity = options.active_velocity;
  ao.min_activation = options.max_passive_activation;
  ao.relative_tolerance = options.relative_tolerance;
  ao.smoothness = options.active_smoothness;
  const ActiveResult act = IdentifyActive(fit, ps.passive, ao);
  ps.active = act.active;
  out.report.Merge(act.report);

  // The ranges the curves were identified over.
  std::vector<double> pa, pv, aa, av;
  for (const TrialColumns& tr : fit) {
    for (std::size_t i = 0; i < tr.size(); ++i) {
      const bool passive_sample = tr.activation[i] <= options.max_passive_activation;
      (passive_sample ? pa : aa).push_back(tr.angle_deg[i]);
      (passive_sample ? pv : av).push_back(tr.velocity_deg_s[i]);
    }
  }
  Provenance& prov = ps.provenance;
  if (!pa.empty()) {
    prov.identified_range_deg["tau_pta"] = RangeOf(pa);
    prov.identified_range_deg_s["tau_ptv"] = RangeOf(pv);
  }
  if (!aa.empty()) {
    prov.identified_range_deg["f_ata"] = RangeOf(aa);
    prov.identified_range_deg_s["f_atv"] = RangeOf(av);
  }

  // 3b. No curve held flat beyond its data (model/extrapolate.h).
  if (options.extrapolate) {
    const double out_lo =
        options.joint_limits ? std::max(0.0, options.joint_limits->min_angle_deg - 10.0) : 0.0;
    const double out_hi =
        options.joint_limits ? std::min(180.0, options.joint_limits->max_angle_deg + 10.0) : 130.0;
    const double vmax = options.extend_velocity_deg_s;
    const CurveRange& ra = prov.identified_range_deg["tau_pta"];
    if (ra.hi - ra.lo >= 5.0) {
      const PassiveAngleForm form =
          FitPassiveAngleForm(ps.passive.torque_angle, ra.lo, ra.hi, options.mgl_prior_nm);
      ps.passive.torque_angle = ExtendPassiveAngle(ps.passive.torque_angle, form, out_lo, out_hi);
      out.report.fit_rms["tau_pta_form_nm"] = form.rms_nm;
      out.report.values["tau_pta_form_mgl_nm"] = form.mgl_nm();
      out.report.values["tau_pta_form_hang_deg"] = form.hang_deg();
    }
    const CurveRange& rv = prov.identified_range_deg_s["tau_ptv"];
    ps.passive.torque_velocity =
        ExtendVelocityCurve(ps.passive.torque_velocity, rv.lo, rv.hi, -vmax, vmax, true);
    const CurveRange& fa = prov.identified_range_deg["f_ata"];
    ps.active.torque_angle =
        ExtendActiveAngle(ps.active.torque_angle, fa.lo, fa.hi, out_lo, out_hi);
    const CurveRange& fv = prov.identified_range_deg_s["f_atv"];
    ps.active.torque_velocity =
        ExtendVelocityCurve(ps.active.torque_velocity, fv.lo, fv.hi, -vmax, vmax, false);
    ps.passive = ReferencePassive(ps.passive);
    ps.active = NormaliseActive(ps.active);
  }

  // 4. Output-error refinement on the free-swing trials (see the file
  //    comment); the linear estimates above are its start and prior.
  if (options.refine_iterations > 0) {
    OutputErrorOptions oe;
    oe.iterations = options.refine_iterations;
    oe.pulse_rate_hz = options.pulse_rate_hz;
    oe.prior_weight = options.refine_prior_weight;
    oe.joint_limits = options.joint_limits;
    const OutputErrorResult refined = RefineOutputError(ps, swing, oe);
    const Provenance keep = ps.provenance;
    ps = refined.parameters;
    ps.provenance = keep;
    out.report.Merge(refined.report);
  }

  // 5. J measured: the releases fix the torque scale the swings leave free.
  out.report.values["inertia_given_kgm2"] = options.inertia_kgm2;
  if (trials.releases.size() >= 2) {
    try {
      const ReleaseInertia ri =
          InertiaFromReleases(trials.swings, trials.releases, options.release_window_s,
                              options.release_max_travel_deg, options.release_min_window_s);
      const double scale = ri.inertia_kgm2 / ps.passive.inertia_kgm2;
      out.report.values["inertia_release_kgm2"] = ri.inertia_kgm2;
      out.report.fit_rms["inertia_releases_nm"] = ri.rms_nm;
      if (scale >= 1.0 / options.max_inertia_scale && scale <= options.max_inertia_scale) {
        const Provenance keep = ps.provenance;
        ps = ScaleTorques(ps, scale);
        ps.provenance = keep;
        ps.provenance.inertia_method = "releases";
      } else {
        out.report.warnings.push_back("the releases give J = " + std::to_string(ri.inertia_kgm2) +
                                      " kg·m², outside the allowed factor of the given " +
                                      std::to_string(options.inertia_kgm2) +
                                      " kg·m²; kept the given J");
      }
    } catch (const std::invalid_argument& e) {
      out.report.warnings.push_back(std::string("J not measured: ") + e.what() +
                                    "; kept the given J");
    }
  }

  ps.provenance.irc_method = std::string(IrcMethodName(kRapidIrcMethod));
  ps.provenance.passive_method = "free_swing_known_inertia";
  ps.provenance.active_method = "log_least_squares";
  ps.provenance.fit_rms = out.report.fit_rms;
  ps.provenance.warnings = out.report.warnings;
  return out;
}

}  // namespace fesbench::model
