#include "model/identify_passive.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "model/grid_golden_search.h"
#include "model/identify_least_squares.h"
#include "model/integrators.h"
#include "model/quality.h"
#include "model/simulate.h"
#include "model/units.h"

namespace fesbench::model {
namespace {

std::size_t CheckColumns(const char* what, const TrialColumns& tr, bool torque, bool activation) {
  const std::size_t n = tr.size();
  if (n < 2) throw std::invalid_argument(std::string(what) + ": trial has fewer than 2 samples");
  RequireColumn(what, "t_s", tr.t_s, n);
  RequireColumn(what, "angle_deg", tr.angle_deg, n);
  RequireColumn(what, "velocity_deg_s", tr.velocity_deg_s, n);
  RequireColumn(what, "accel_deg_s2", tr.accel_deg_s2, n);
  if (torque) RequireColumn(what, "torque_nm", tr.torque_nm, n);
  if (activation) RequireColumn(what, "activation", tr.activation, n);
  return n;
}

std::vector<double> Gather(std::span<const TrialColumns> trials,
                           const std::vector<std::vector<std::size_t>>& rows,
                           std::vector<double> TrialColumns::*column) {
  std::vector<double> out;
  for (std::size_t k = 0; k < trials.size(); ++k) {
    for (std::size_t i : rows[k]) out.push_back((trials[k].*column)[i]);
  }
  return out;
}

// The breakpoints the passive fits share (Eq. 4.31, Eq. 4.35, §7.4.1):
// [X(θ) | X(θ̇) | extra columns]·c = b over the passive samples, τ_pta and
// τ_ptv piecewise linear (Eq. 4.30) on breakpoints resolved over the
// samples. The caller adds the rows (PwlLeastSquares) and solves.
struct PassiveSystem {
  std::vector<double> bp_a, bp_v;
  Eigen::Index ma = 0, mv = 0;
};

PassiveSystem MakePassiveSystem(const char* what, std::span<const double> angle,
                                std::span<const double> velocity, const BreakpointSpec& angle_spec,
                                const BreakpointSpec& velocity_spec, Eigen::Index extra) {
  PassiveSystem sys;
  sys.bp_a = ResolveBreakpoints(angle_spec, angle);
  sys.bp_v = ResolveBreakpoints(velocity_spec, velocity);
  sys.ma = static_cast<Eigen::Index>(sys.bp_a.size());
  sys.mv = static_cast<Eigen::Index>(sys.bp_v.size());
  if (angle.size() < static_cast<std::size_t>(sys.ma + sys.mv + extra)) {
    throw std::invalid_argument(std::string(what) + ": fewer passive samples than parameters");
  }
  return sys;
}

// τ_pta and τ_ptv from a solution's first ma + mv coefficients (not yet
// referenced, §6.5).
PassiveParams PassiveCurves(const PassiveSystem& sys, const Eigen::VectorXd& c) {
  PassiveParams p;
  p.torque_angle = PiecewiseLinear(sys.bp_a, std::vector<double>(c.data(), c.data() + sys.ma));
  p.torque_velocity =
      PiecewiseLinear(sys.bp_v, std::vector<double>(c.data() + sys.ma, c.data() + sys.ma + sys.mv));
  return p;
}

// Warnings for breakpoints the samples hardly reach (Eq. 4.30 support).
void AddSupportWarnings(const PassiveSystem& sys, std::span<const double> angle,
                        std::span<const double> velocity, double min_support,
                        IdentifyReport& report) {
  for (auto& w :
       SupportWarnings("tau_pta", "deg", sys.bp_a, BreakpointSupport(sys.bp_a, angle), min_support))
    report.warnings.push_back(std::move(w));
  for (auto& w : SupportWarnings("tau_ptv", "deg/s", sys.bp_v,
                                 BreakpointSupport(sys.bp_v, velocity), min_support))
    report.warnings.push_back(std::move(w));
}

// A passive stretch of a free-swing trial (FreeSwingPassiveOptions::
// output_error_inertia): its measured first state, the muscle at rest, and
// the measured angles the simulated swing is to match.
struct SwingStretch {
  double angle_deg = 0.0;
  double velocity_deg_s = 0.0;
  double rate_hz = 0.0;
  std::span<const double> measured_deg;
};

// The cost of one J over the stretches, with its derivative and
// Gauss–Newton curvature in u = ln J when asked for.
struct SwingCost {
  double cost = std::numeric_limits<double>::infinity();
  double gradient = 0.0;
  double curvature = 0.0;
};

// The segments of a piecewise-linear curve held at its ends (Eq. 4.27),
// one per interval between breakpoints and one beyond each end: segment i
// of m + 1 is [lower[i], lower[i + 1]) with lower = {NaN, x₀, …, x_{m−1},
// NaN} (no comparison with NaN holds, so a scan stops at the held ends),
// and its line is stored as y = c₀ + c₁·x: from x to y one multiply-add,
// no subtraction of the segment's start (as JointModel's LinePairTable).
struct SegmentScan {
  std::vector<double> lower;

  explicit SegmentScan(const std::vector<double>& x) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    lower.reserve(x.size() + 2);
    lower.push_back(nan);
    lower.insert(lower.end(), x.begin(), x.end());
    lower.push_back(nan);
  }
  // The segment of x, the scan started at the last one (a trajectory
  // rarely leaves it). NaN stays where it is and evaluates to NaN.
  [[gnu::always_inline]] std::size_t Find(double x, std::size_t& hint) const {
    std::size_t i = hint;
    while (x < lower[i]) --i;
    while (x >= lower[i + 1]) ++i;
    hint = i;
    return i;
  }
  // The lines c₀ + c₁·x of `curve` per segment (ends held).
  static void Lines(const PiecewiseLinear& curve, std::vector<double>& c0,
                    std::vector<double>& c1) {
    const std::vector<double>& cx = curve.x();
    const std::vector<double>& cy = curve.y();
    const std::size_t m = cx.size();
    c0.assign(m + 1, 0.0);
    c1.assign(m + 1, 0.0);
    c0[0] = cy[0];
    c0[m] = cy[m - 1];
    for (std::size_t i = 1; i < m; ++i) {
      c1[i] = (cy[i] - cy[i - 1]) / (cx[i] - cx[i - 1]);
      c0[i] = cy[i - 1] - c1[i] * cx[i - 1];
    }
  }
};

// The free swings of the passive leg through the stretches for J = e^u:
//   J·θ̈ = −τ_pta(θ) − τ_ptv(θ̇),  τ_ptv = P_b − J·P_a
// (Eq. 4.35 refitted for each J), integrated as SimulateFreeSwing does
// (RK4 in equal steps of at most 1 ms between output samples, simulate.h)
// into no storage: each sample's error goes straight into the sum. For each
// J the curves are first scaled into θ̈ terms, A(θ) = −k·τ_pta(θ) and
// Q(θ̇) = k·(J·P_a − P_b)(θ̇), k = (180/π)/J, so a stage is θ̈ = A + Q (the
// workspace: rewritten per J, never reallocated). With the derivative, the
// tangent ∂(θ, θ̇)/∂u goes through every RK4 stage with the state: the
// derivative of the discrete map itself, so the minimum found from it is
// that of the cost the grid evaluates.
class PassiveSwings {
 public:
  PassiveSwings(const PiecewiseLinear& tau_pta, const PiecewiseLinear& p_b,
                const PiecewiseLinear& p_a, std::vector<SwingStretch> stretches)
      : angle_(tau_pta.x()), velocity_(p_b.x()), stretches_(std::move(stretches)) {
    SegmentScan::Lines(tau_pta, pta0_, pta1_);
    SegmentScan::Lines(p_b, pb0_, pb1_);
    SegmentScan::Lines(p_a, pa0_, pa1_);
    a_.resize(pta0_.size());
    v_.resize(pb0_.size());
    cells_.resize(a_.size() * v_.size());
    // The RK4 steps between output samples, as SimulateFreeSwing takes
    // them: equal steps of at most 1 ms over 1/rate (the same for every
    // sample of a stretch up to the rounding of t_i − t_{i−1}, and for
    // every J; computed once).
    for (const SwingStretch& st : stretches_) {
      samples_ += st.measured_deg.size();
      const double span = 1.0 / st.rate_hz;
      const long m = EvenStepCount(span, kStepS);
      steps_.push_back({m, span / static_cast<double>(m)});
    }
  }

  std::size_t samples() const { return samples_; }

  // Σ (θ_sim − θ_measured)² over every stretch; +∞ for a non-finite
  // simulation or once the partial sum exceeds `bound` (the sum only grows).
  SwingCost Cost(double u, bool derivative,
                 double bound = std::numeric_limits<double>::infinity()) {
    const double j = std::exp(u);
    const double k = RadToDeg(1.0 / j);  // N·m → deg/s²
    for (std::size_t i = 0; i < a_.size(); ++i) a_[i] = {-k * pta0_[i], -k * pta1_[i]};
    for (std::size_t i = 0; i < v_.size(); ++i) {
      v_[i] = {k * (j * pa0_[i] - pb0_[i]), k * (j * pa1_[i] - pb1_[i]), k * pb0_[i], k * pb1_[i]};
    }
    ++pass_;
    return derivative ? Run<true>(bound) : Run<false>(bound);
  }

 private:
  static constexpr double kStepS = 1e-3;  // SimulationOptions::step_s

  // A(θ) = a₀ + a₁·θ on an angle segment; Q(θ̇) = q₀ + q₁·θ̇ and
  // G(θ̇) = g₀ + g₁·θ̇ (below) on a velocity segment.
  struct AngleLine {
    double a0, a1;
  };
  struct VelocityLine {
    double q0, q1, g0, g1;
  };

  template <bool kDerivative>
  SwingCost Run(double bound) {
    std::size_t seg_a = 1, seg_v = 1;
    double cost = 0.0, gradient = 0.0, curvature = 0.0;
    for (std::size_t k = 0; k < stretches_.size(); ++k) {
      const SwingStretch& st = stretches_[k];
      const auto [m, h] = steps_[k];
      double th = st.angle_deg, om = st.velocity_deg_s, dth = 0.0, dom = 0.0;
      for (std::size_t i = 0; i < st.measured_deg.size(); ++i) {
        for (long s = 0; i > 0 && s < m; ++s) {
          // Inside its cell by the margins: the cell's affine step.
          const CellStep& c = CellAt(angle_.Find(th, seg_a), velocity_.Find(om, seg_v), h);
          if (th >= c.lo_a && th < c.hi_a && om >= c.lo_v && om < c.hi_v) {
            if constexpr (kDerivative) {
              const double dth1 = (c.t00 * th + c.t01 * om + c.t02) + (c.s00 * dth + c.s01 * dom);
              dom = (c.t10 * th + c.t11 * om + c.t12) + (c.s10 * dth + c.s11 * dom);
              dth = dth1;
            }
            const double th1 = c.s00 * th + c.s01 * om + c.s02;
            om = c.s10 * th + c.s11 * om + c.s12;
            th = th1;
          } else {
            Step<kDerivative>(h, th, om, dth, dom, seg_a, seg_v);
          }
        }
        const double e = th - st.measured_deg[i];
        cost += e * e;
        if constexpr (kDerivative) {
          gradient += e * dth;
          curvature += dth * dth;
        }
        if (cost > bound) return {};
      }
    }
    if (!std::isfinite(cost)) return {};
    return {cost, 2.0 * gradient, 2.0 * curvature};
  }

  // One step of Rk4Step (integrators.h) on (θ, θ̇), θ̈ = A(θ) + Q(θ̇), and
  // with the derivative on its tangent (dθ, dθ̇) = ∂(θ, θ̇)/∂u, whose θ̈
  // is A′(θ)·dθ + Q′(θ̇)·dθ̇ + ∂θ̈/∂u, ∂θ̈/∂u = J·∂θ̈/∂J =
  // k·(τ_pta + P_b) = G − A with G = k·P_b. The stages are the classical
  // ones, θ_k = θ + c_k·θ̇_{k−1} and θ̇_{k+1} = θ̇ + c_{k+1}·θ̈_k, arranged so
  // that from one stage's velocity to the next's is short: on the
  // segments' lines θ̇ + c·θ̈(θ_k, θ̇_k) = (θ̇ + c·(a₀ + a₁·θ + q₀)) +
  // (c·a₁·c_k)·θ̇_{k−1} + (c·q₁)·θ̇_k, each velocity one multiply-add
  // from the last (the segments are found from θ_k and θ̇_k, predicted
  // branches). The same map up to rounding.
  template <bool kDerivative>
  [[gnu::always_inline]] void Step(double h, double& th, double& om, double& dth, double& dom,
                                   std::size_t& seg_a, std::size_t& seg_v) const {
    const double hh = 0.5 * h, h6 = h / 6.0;
    const AngleLine& l1 = a_[angle_.Find(th, seg_a)];
    const VelocityLine& v1 = v_[velocity_.Find(om, seg_v)];
    const double a1 = l1.a0 + l1.a1 * th;  // A(θ₁), θ₁ = θ
    const double acc1 = (a1 + v1.q0) + v1.q1 * om;
    const double om2 = (hh * (a1 + v1.q0)) + (1.0 + hh * v1.q1) * om;

    const AngleLine& l2 = a_[angle_.Find(th + hh * om, seg_a)];
    const VelocityLine& v2 = v_[velocity_.Find(om2, seg_v)];
    const double a2 = (l2.a0 + l2.a1 * th) + (l2.a1 * hh) * om;  // A(θ + (h/2)·θ̇)
    const double acc2 = (a2 + v2.q0) + v2.q1 * om2;
    const double om3 = (om + hh * (a2 + v2.q0)) + (hh * v2.q1) * om2;

    const AngleLine& l3 = a_[angle_.Find(th + hh * om2, seg_a)];
    const VelocityLine& v3 = v_[velocity_.Find(om3, seg_v)];
    const double a3_base = l3.a0 + l3.a1 * th;  // A(θ₃) = a3_base + a₁·(h/2)·θ̇₂
    const double a3 = a3_base + (l3.a1 * hh) * om2;
    const double acc3 = (a3 + v3.q0) + v3.q1 * om3;
    const double om4 = ((om + h * (a3_base + v3.q0)) + (h * hh * l3.a1) * om2) + (h * v3.q1) * om3;

    const AngleLine& l4 = a_[angle_.Find(th + h * om3, seg_a)];
    const VelocityLine& v4 = v_[velocity_.Find(om4, seg_v)];
    const double a4_base = l4.a0 + l4.a1 * th;  // A(θ₄) = a4_base + a₁·h·θ̇₃
    const double a4 = a4_base + (l4.a1 * h) * om3;
    const double sum3 = acc1 + 2.0 * acc2 + 2.0 * acc3;
    if constexpr (kDerivative) {
      const double d1 = l1.a1 * dth + v1.q1 * dom + ((v1.g0 + v1.g1 * om) - a1);
      const double dom2 = dom + hh * d1;
      const double d2 = l2.a1 * (dth + hh * dom) + v2.q1 * dom2 + ((v2.g0 + v2.g1 * om2) - a2);
      const double dom3 = dom + hh * d2;
      const double d3 = l3.a1 * (dth + hh * dom2) + v3.q1 * dom3 + ((v3.g0 + v3.g1 * om3) - a3);
      const double dom4 = dom + h * d3;
      const double d4 = l4.a1 * (dth + h * dom3) + v4.q1 * dom4 + ((v4.g0 + v4.g1 * om4) - a4);
      dth = dth + h6 * (dom + 2.0 * dom2 + 2.0 * dom3 + dom4);
      dom = dom + h6 * (d1 + 2.0 * d2 + 2.0 * d3 + d4);
    }
    th = th + h6 * (om + 2.0 * om2 + 2.0 * om3 + om4);
    om = ((om + h6 * (sum3 + (a4_base + v4.q0))) + (h6 * h * l4.a1) * om3) + (h6 * v4.q1) * om4;
  }

  SegmentScan angle_;     // τ_pta's breakpoints
  SegmentScan velocity_;  // P_b's and P_a's (the same, Eq. 4.35's)
  // Where A and Q are lines — in a cell, a segment of each — the equation
  // and its tangent are linear, ż = B·z + b with z = (θ, θ̇, dθ, dθ̇):
  //   θ̈ = a₁·θ + q₁·θ̇ + (a₀ + q₀),
  //   dθ̈ = −a₁·θ + g₁·θ̇ + a₁·dθ + q₁·dθ̇ + (g₀ − a₀),
  // and an RK4 step of it is affine: z′ = R·z + p with
  // R = Σ_{k≤4} (h·B)^k/k!, p = Σ_{k≤3} (h·B)^k/(k+1)!·(h·b). It is the four
  // stages' map (up to rounding) while every stage stays in the cell,
  // which holds when the state is inside it by the margins h·max|θ̇| in θ
  // and h·max|θ̈| in θ̇ (maxima over the cell; each stage moves θ by c·θ̇_k
  // and θ̇ by c·θ̈_k, c ≤ h). A step there is two (four with the tangent)
  // dot products instead of four stages; elsewhere (a stage crossing a
  // breakpoint, the unbounded end segments) the stages. Per cell, computed
  // when a pass first enters it.
  struct CellStep {
    long pass = -1;
    double h = 0.0;
    double lo_a = 0.0, hi_a = 0.0, lo_v = 0.0, hi_v = 0.0;  // the state's box
    // θ′ = s00·θ + s01·θ̇ + s02, θ̇′ likewise (s1·); dθ′ = t00·θ + t01·θ̇ +
    // s00·dθ + s01·dθ̇ + t02, dθ̇′ likewise (t1·, s1·).
    double s00, s01, s02, s10, s11, s12, t00, t01, t02, t10, t11, t12;
  };

  // 2 × 2 blocks of h·B: B = [M 0; N M], M = [0 1; a₁ q₁], N = [0 0; −a₁ g₁].
  struct Block {
    double m00, m01, m10, m11;
    Block operator*(const Block& o) const {
      return {m00 * o.m00 + m01 * o.m10, m00 * o.m01 + m01 * o.m11, m10 * o.m00 + m11 * o.m10,
              m10 * o.m01 + m11 * o.m11};
    }
    Block operator+(const Block& o) const {
      return {m00 + o.m00, m01 + o.m01, m10 + o.m10, m11 + o.m11};
    }
    Block operator*(double k) const { return {k * m00, k * m01, k * m10, k * m11}; }
  };

  const CellStep& CellAt(std::size_t ia, std::size_t iv, double h) {
    CellStep& c = cells_[ia * v_.size() + iv];
    if (c.pass == pass_ && c.h == h) return c;
    c.pass = pass_;
    c.h = h;
    const AngleLine& a = a_[ia];
    const VelocityLine& v = v_[iv];
    // (h·B)^k = [H^k 0; L_k H^k], L₁ = K, L_{k+1} = K·H^k + H·L_k.
    const Block hm{0.0, h, h * a.a1, h * v.q1}, hn{0.0, 0.0, -h * a.a1, h * v.g1};
    const Block h2 = hm * hm, h3 = h2 * hm, h4 = h3 * hm;
    const Block l2 = hn * hm + hm * hn, l3 = hn * h2 + hm * l2, l4 = hn * h3 + hm * l3;
    const Block id{1.0, 0.0, 0.0, 1.0};
    const Block r = id + hm + h2 * 0.5 + h3 * (1.0 / 6.0) + h4 * (1.0 / 24.0);
    const Block q = hn + l2 * 0.5 + l3 * (1.0 / 6.0) + l4 * (1.0 / 24.0);
    const Block sp = id + hm * 0.5 + h2 * (1.0 / 6.0) + h3 * (1.0 / 24.0);
    const Block tp = hn * 0.5 + l2 * (1.0 / 6.0) + l3 * (1.0 / 24.0);
    // p = [sp 0; tp sp]·h·b, h·b = (0, h·(a₀ + q₀), 0, h·(g₀ − a₀)).
    const double b1 = h * (a.a0 + v.q0), b3 = h * (v.g0 - a.a0);
    c.s00 = r.m00, c.s01 = r.m01, c.s02 = sp.m01 * b1;
    c.s10 = r.m10, c.s11 = r.m11, c.s12 = sp.m11 * b1;
    c.t00 = q.m00, c.t01 = q.m01, c.t02 = tp.m01 * b1 + sp.m01 * b3;
    c.t10 = q.m10, c.t11 = q.m11, c.t12 = tp.m11 * b1 + sp.m11 * b3;
    // The cell [θ_lo, θ_hi) × [θ̇_lo, θ̇_hi) (±∞ at the held ends) and
    // the margins; an unbounded maximum leaves no box.
    constexpr double kInf = std::numeric_limits<double>::infinity();
    const auto lower = [](double x) { return std::isnan(x) ? -kInf : x; };
    const auto upper = [](double x) { return std::isnan(x) ? kInf : x; };
    const double th_lo = lower(angle_.lower[ia]), th_hi = upper(angle_.lower[ia + 1]);
    const double om_lo = lower(velocity_.lower[iv]), om_hi = upper(velocity_.lower[iv + 1]);
    const double om_max = std::max(std::abs(om_lo), std::abs(om_hi));
    // max |θ̈| over the cell: at a corner (|affine| is convex); a
    // variable without a term in θ̈ (a held end's slope 0) is left out.
    double acc_max = 0.0;
    for (const double th : {th_lo, th_hi}) {
      for (const double om : {om_lo, om_hi}) {
        const double acc =
            (a.a0 + v.q0) + (a.a1 != 0.0 ? a.a1 * th : 0.0) + (v.q1 != 0.0 ? v.q1 * om : 0.0);
        acc_max = std::max(acc_max, std::isnan(acc) ? kInf : std::abs(acc));
      }
    }
    const double m_th = h * om_max, m_om = h * acc_max;
    if (!std::isfinite(m_th) || !std::isfinite(m_om)) {
      c.lo_a = c.lo_v = kInf;
      c.hi_a = c.hi_v = -kInf;
    } else {
      c.lo_a = th_lo + m_th;
      c.hi_a = th_hi - m_th;
      c.lo_v = om_lo + m_om;
      c.hi_v = om_hi - m_om;
    }
    return c;
  }

  std::vector<SwingStretch> stretches_;
  std::size_t samples_ = 0;
  struct Steps {
    long count;
    double h;
  };
  std::vector<Steps> steps_;     // per stretch: between two samples
  std::vector<CellStep> cells_;  // angle segment × velocity segment
  long pass_ = 0;
  // The curves' own lines, and their per-J θ̈ terms (A, Q, G above).
  std::vector<double> pta0_, pta1_, pb0_, pb1_, pa0_, pa1_;
  std::vector<AngleLine> a_;
  std::vector<VelocityLine> v_;
};

// ln J minimising the stretches' angle error over [lo, hi]: the cost on a
// grid of 25 points (a coarse scan against local minima), then refined
// inside the best point's two grid cells by Gauss–Newton steps on the
// derivative (a step that does not lower the cost shrinks the bracket and
// halves toward it) until a step is below 1e-8 in ln J. The grid is
// evaluated nearest `start` (the equation-error J) first, outwards, and a
// point stops simulating once its partial sum exceeds the best so far: it
// cannot be the minimum, and the grid's choice is the one a full
// evaluation makes.
ScalarMinimum FitLogInertia(PassiveSwings& swings, double lo, double hi, double start) {
  constexpr int kGridSteps = 24;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const double step = (hi - lo) / kGridSteps;
  const auto grid_x = [&](long i) { return lo + step * static_cast<double>(i); };
  std::array<double, kGridSteps + 1> cost;
  cost.fill(kInf);
  const long first =
      std::isfinite(start) ? std::clamp(std::lround((start - lo) / step), 0L, long{kGridSteps}) : 0;
  // The first point with its derivative: usually the best, where the
  // refinement starts.
  const SwingCost at_first = swings.Cost(grid_x(first), true);
  cost[static_cast<std::size_t>(first)] = at_first.cost;
  double best = at_first.cost;
  for (long d = 1; d <= kGridSteps; ++d) {
    for (const long i : {first - d, first + d}) {
      if (i < 0 || i > kGridSteps) continue;
      cost[static_cast<std::size_t>(i)] = swings.Cost(grid_x(i), false, best).cost;
      best = std::min(best, cost[static_cast<std::size_t>(i)]);
    }
  }
  long best_i = 0;
  for (long i = 1; i <= kGridSteps; ++i) {
    if (cost[static_cast<std::size_t>(i)] < cost[static_cast<std::size_t>(best_i)]) best_i = i;
  }
  double u = grid_x(best_i);
  if (!std::isfinite(cost[static_cast<std::size_t>(best_i)])) return {u, kInf};
  double a = u - step, b = u + step;
  SwingCost at = best_i == first ? at_first : swings.Cost(u, true);
  for (int it = 0; it < 60 && at.curvature > 0.0 && at.gradient != 0.0; ++it) {
    const double delta = -at.gradient / at.curvature;
    (at.gradient > 0.0 ? b : a) = u;  // the minimum is downhill
    double next = u + delta;
    if (!(next > a && next < b)) next = 0.5 * (u + (delta > 0.0 ? b : a));
    if (std::abs(next - u) < 1e-8) break;
    const SwingCost c = swings.Cost(next, true);
    if (c.cost < at.cost) {
      u = next;
      at = c;
    } else {
      (next > u ? b : a) = next;  // a minimum lies between u and next
    }
  }
  return {u, at.cost};
}

}  // namespace

std::string_view PassiveMethodName(PassiveMethod method) {
  switch (method) {
    case PassiveMethod::kSequential:
      return "sequential";
    case PassiveMethod::kSimultaneous:
      return "simultaneous";
    case PassiveMethod::kFreeSwing:
      return "free_swing";
  }
  return "unknown";
}

std::optional<PassiveMethod> PassiveMethodFromName(std::string_view name) {
  for (PassiveMethod m : kPassiveMethods) {
    if (PassiveMethodName(m) == name) return m;
  }
  return std::nullopt;
}

double AnthropometricInertia(double body_mass_kg, double leg_length_m) {
  if (!(body_mass_kg > 0.0) || !(leg_length_m > 0.0) || !std::isfinite(body_mass_kg) ||
      !std::isfinite(leg_length_m)) {
    throw std::invalid_argument("AnthropometricInertia: mass and length must be finite and > 0");
  }
  const double r = 0.735 * leg_length_m;  // radius of gyration
  return 0.061 * body_mass_kg * r * r;    // Eq. 4.13
}

double AnthropometricGravityMoment(double body_mass_kg, double leg_length_m) {
  if (!(body_mass_kg > 0.0) || !(leg_length_m > 0.0) || !std::isfinite(body_mass_kg) ||
      !std::isfinite(leg_length_m)) {
    throw std::invalid_argument(
        "AnthropometricGravityMoment: mass and length must be finite and > 0");
  }
  return 0.061 * body_mass_kg * kStandardGravity_m_s2 * 0.606 * leg_length_m;
}

PassiveResult IdentifyPassiveSequential(const TrialColumns& positions,
                                        const TrialColumns& velocities,
                                        const SequentialPassiveOptions& options) {
  const char* what = "IdentifyPassiveSequential";
  {
    const std::size_t n = positions.size();
    RequireColumn(what, "t_s", positions.t_s, n);
    RequireColumn(what, "angle_deg", positions.angle_deg, n);
    RequireColumn(what, "torque_nm", positions.torque_nm, n);
  }
  PassiveResult res;
  // Eq. 4.10: static torque at each hold, both directions averaged (§5.4.1).
  const auto holds = DetectHolds(positions.t_s, positions.angle_deg, positions.torque_nm,
                                 positions.accel_deg_s2.size() == positions.size()
                                     ? std::span<const double>(positions.accel_deg_s2)
                                     : std::span<const double>(),
                                 options.holds);
  if (holds.empty()) throw std::invalid_argument(std::string(what) + ": no position hold found");
  const PiecewiseLinear pta = AverageHoldsByAngle(holds, false, options.hold_tolerance_deg);
  res.report.values["holds"] = static_cast<double>(holds.size());

  // Eq. 4.12 on the constant-velocity part of every move.
  const std::size_t n = velocities.size();
  RequireColumn(what, "t_s", velocities.t_s, n);
  RequireColumn(what, "angle_deg", velocities.angle_deg, n);
  RequireColumn(what, "velocity_deg_s", velocities.velocity_deg_s, n);
  RequireColumn(what, "torque_nm", velocities.torque_nm, n);
  std::vector<double> vx = {0.0}, vy = {0.0};  // τ_ptv(0) = 0 by construction
  double ss = 0.0;
  std::size_t used = 0;
  const auto& v = velocities.velocity_deg_s;
  for (std::size_t i = 0; i < n;) {
    if (std::abs(v[i]) < options.min_move_speed_deg_s) {
      ++i;
      continue;
    }
    const double sign = v[i] > 0 ? 1.0 : -1.0;
    std::size_t j = i;
    double peak = 0.0;
    while (j < n && sign * v[j] >= options.min_move_speed_deg_s)
      peak = std::max(peak, sign * v[j++]);
    // Constant part: |θ̇| within tolerance of the peak; its last use_last_s.
    std::size_t last = j;
    while (last > i && sign * v[last - 1] < (1.0 - options.constant_velocity_tolerance) * peak)
      --last;
    std::size_t first = last;
    while (first > i && sign * v[first - 1] >= (1.0 - options.constant_velocity_tolerance) * peak &&
           velocities.t_s[last - 1] - velocities.t_s[first - 1] < options.use_last_s - 1e-9) {
      --first;
    }
    if (last - first >= 5) {
      double sv = 0.0, st = 0.0;
      for (std::size_t k = first; k < last; ++k) {
        sv += v[k];
        st += velocities.torque_nm[k] - pta(velocities.angle_deg[k]);
      }
      const double cnt = static_cast<double>(last - first);
      vx.push_back(sv / cnt);
      vy.push_back(st / cnt);
      for (std::size_t k = first; k < last; ++k) {
        const double e = velocities.torque_nm[k] - pta(velocities.angle_deg[k]) - st / cnt;
        ss += e * e;
      }
      used += last - first;
    }
    i = j;
  }
  if (vx.size() < 2)
    throw std::invalid_argument(std::string(what) + ": no constant-velocity move found");
  // Sort; equal velocities (repeated moves) are averaged.
  std::vector<std::size_t> idx(vx.size());
  for (std::size_t k = 0; k < idx.size(); ++k) idx[k] = k;
  std::sort(idx.begin(), idx.end(), [&](auto a, auto b) { return vx[a] < vx[b]; });
  std::vector<double> x, y;
  for (std::size_t k = 0; k < idx.size();) {
    std::size_t m = k;
    double sx = 0.0, sy = 0.0;
    while (m < idx.size() && vx[idx[m]] - vx[idx[k]] < 0.05)
      sx += vx[idx[m]], sy += vy[idx[m]], ++m;
    x.push_back(sx / static_cast<double>(m - k));
    y.push_back(sy / static_cast<double>(m - k));
    k = m;
  }
  res.report.values["velocity_moves"] = static_cast<double>(vx.size() - 1);
  res.report.fit_rms["tau_ptv_window_nm"] =
      used > 0 ? std::sqrt(ss / static_cast<double>(used)) : 0.0;

  PassiveParams p;
  p.torque_angle = pta;
  p.torque_velocity = PiecewiseLinear(std::move(x), std::move(y));
  if (options.body_mass_kg && options.leg_length_m) {
    p.inertia_kgm2 = AnthropometricInertia(*options.body_mass_kg, *options.leg_length_m);
  } else {
    p.inertia_kgm2 = options.inertia_kgm2;
    res.report.warnings.push_back(
        "sequential: no body mass / leg length, inertia taken from the options (Eq. 4.13 not "
        "used)");
  }
  res.passive = ReferencePassive(p);  // §6.5
  return res;
}

PassiveResult IdentifyPassiveSimultaneous(std::span<const TrialColumns> trials,
                                          const SimultaneousPassiveOptions& options) {
  const char* what = "IdentifyPassiveSimultaneous";
  std::vector<std::vector<std::size_t>> rows(trials.size());
  std::size_t total = 0;
  for (std::size_t k = 0; k < trials.size(); ++k) {
    const std::size_t n = CheckColumns(what, trials[k], true, false);
    const bool act = trials[k].activation.size() == n;
    for (std::size_t i = 0; i < n; ++i) {
      if (!act || trials[k].activation[i] <= options.max_activation) rows[k].push_back(i);
    }
    total += rows[k].size();
  }
  const auto angle = Gather(trials, rows, &TrialColumns::angle_deg);
  const auto vel = Gather(trials, rows, &TrialColumns::velocity_deg_s);
  const auto acc = Gather(trials, rows, &TrialColumns::accel_deg_s2);
  const auto tq = Gather(trials, rows, &TrialColumns::torque_nm);
  // Eq. 4.31: [X(θ) | X(θ̇) | θ̈] · c = τ.
  const PassiveSystem sys = MakePassiveSystem(what, angle, vel, options.angle, options.velocity, 1);
  const Eigen::Index ma = sys.ma, mv = sys.mv;
  PwlLeastSquares design(sys.bp_a, sys.bp_v, 1, 1, total);
  for (std::size_t i = 0; i < total; ++i) {
    const double acc_rad = DegToRad(acc[i]);
    design.AddRow(angle[i], vel[i], std::span(&acc_rad, 1), std::span(&tq[i], 1));
  }
  const LeastSquaresSolution sol = SolveTruncatedSvd(design.Reduced(0), options.relative_tolerance);
  PassiveParams p = PassiveCurves(sys, sol.c);
  p.inertia_kgm2 = sol.c(ma + mv);
  PassiveResult res;
  res.passive = ReferencePassive(p);  // §6.5
  res.report.fit_rms["passive_nm"] = sol.rms;
  res.report.values["passive_rank"] = sol.rank;
  res.report.values["passive_parameters"] = static_cast<double>(ma + mv + 1);
  res.report.values["passive_samples"] = static_cast<double>(total);
  // One null direction is inherent (the constant shared by τ_pta and τ_ptv).
  if (sol.rank < ma + mv) {
    res.report.warnings.push_back("simultaneous passive: rank " + std::to_string(sol.rank) +
                                  " of " + std::to_string(ma + mv + 1) +
                                  " parameters (under-determined; shortest solution used)");
  }
  AddSupportWarnings(sys, angle, vel, options.min_support, res.report);
  if (!(p.inertia_kgm2 > 0.0))
    res.report.warnings.push_back("simultaneous passive: inertia not positive");
  const Coverage cov = PhasePlaneCoverage(angle, vel, sys.bp_a, sys.bp_v);
  res.report.values["coverage"] = cov.share;
  if (auto w = CoverageWarning("simultaneous passive", cov, options.coverage_warn_below);
      !w.empty()) {
    res.report.warnings.push_back(std::move(w));
  }
  return res;
}

PassiveResult IdentifyPassiveFreeSwing(std::span<const TrialColumns> trials,
                                       const PiecewiseLinear& torque_angle,
                                       const FreeSwingPassiveOptions& options) {
  const char* what = "IdentifyPassiveFreeSwing";
  if (torque_angle.empty()) throw std::invalid_argument(std::string(what) + ": tau_pta is empty");
  std::vector<std::vector<std::size_t>> rows(trials.size());
  std::size_t total = 0;
  for (std::size_t k = 0; k < trials.size(); ++k) {
    const std::size_t n = CheckColumns(what, trials[k], false, true);
    for (std::size_t i = 0; i < n; ++i) {
      if (trials[k].activation[i] <= options.max_activation) rows[k].push_back(i);  // §5.4.3
    }
    total += rows[k].size();
  }
  const auto angle = Gather(trials, rows, &TrialColumns::angle_deg);
  const auto vel = Gather(trials, rows, &TrialColumns::velocity_deg_s);
  const auto acc = Gather(trials, rows, &TrialColumns::accel_deg_s2);
  const auto bp_v = ResolveBreakpoints(options.velocity, vel);
  const Eigen::Index mv = static_cast<Eigen::Index>(bp_v.size());
  if (total < static_cast<std::size_t>(mv + 1)) {
    throw std::invalid_argument(std::string(what) + ": fewer passive samples than parameters");
  }
  // Eq. 4.35: −τ_pta(θ) = Σ c_k X_k(θ̇) + J·θ̈. With J found by output
  // error, τ_ptv for a fixed J too: Eq. 4.35 with J·θ̈ moved to the right,
  // X(θ̇)·c = −τ_pta(θ) − J·θ̈; the least-squares solution is linear in the
  // right-hand side, so τ_ptv(J) = P_b − J·P_a with P_b, P_a the solutions
  // for −τ_pta(θ) and θ̈.
  PwlLeastSquares design(bp_v, {}, 1, 1, total);
  PwlLeastSquares velocity_only(bp_v, {}, 0, options.output_error_inertia ? 2 : 0,
                                options.output_error_inertia ? total : 0);
  std::size_t segment = 0;
  for (std::size_t i = 0; i < total; ++i) {
    const double acc_rad = DegToRad(acc[i]);
    const double rhs[2] = {-torque_angle(angle[i], segment), acc_rad};
    design.AddRow(vel[i], 0.0, std::span(&acc_rad, 1), std::span(rhs, 1));
    if (options.output_error_inertia) velocity_only.AddRow(vel[i], 0.0, {}, rhs);
  }
  const LeastSquaresSolution sol = SolveTruncatedSvd(design.Reduced(0), options.relative_tolerance);
  PassiveParams p;
  p.torque_angle = torque_angle;
  p.torque_velocity = PiecewiseLinear(bp_v, std::vector<double>(sol.c.data(), sol.c.data() + mv));
  p.inertia_kgm2 = sol.c(mv);
  PassiveResult res;
  if (options.output_error_inertia) {
    const Eigen::VectorXd c_b =
        SolveTruncatedSvd(velocity_only.Reduced(0), options.relative_tolerance).c;
    const Eigen::VectorXd c_a =
        SolveTruncatedSvd(velocity_only.Reduced(1), options.relative_tolerance).c;
    const auto ptv_for = [&](double j) {
      const Eigen::VectorXd c = c_b - j * c_a;
      return PiecewiseLinear(bp_v, std::vector<double>(c.data(), c.data() + mv));
    };
    // Passive stretches of the trials (first state measured, muscle at rest).
    struct Segment {
      const TrialColumns* trial;
      std::size_t begin, end;
    };
    const auto find_segments = [&](double excursion_deg) {
      std::vector<Segment> segments;
      for (std::size_t k = 0; k < trials.size(); ++k) {
        const TrialColumns& tr = trials[k];
        const double rate = tr.SampleRateHz();
        const auto min_n = static_cast<std::size_t>(std::ceil(options.min_segment_s * rate));
        const auto max_n =
            std::max<std::size_t>(min_n, static_cast<std::size_t>(options.max_segment_s * rate));
        const std::vector<std::size_t>& idx = rows[k];
        std::size_t i = 0;
        while (i < idx.size()) {
          std::size_t j = i;
          const auto free = [&](std::size_t q) {
            if (!options.joint_limits) return true;
            const double th = tr.angle_deg[idx[q]];
            return th > options.joint_limits->min_angle_deg + options.stop_margin_deg &&
                   th < options.joint_limits->max_angle_deg - options.stop_margin_deg;
          };
          if (!free(i) || tr.activation[idx[i]] > options.segment_max_activation) {
            ++i;
            continue;
          }
          while (j + 1 < idx.size() && idx[j + 1] == idx[j] + 1 && j + 1 - i < max_n &&
                 free(j + 1) && tr.activation[idx[j + 1]] <= options.segment_max_activation)
            ++j;
          // The small-oscillation tail cut off (min_segment_excursion_deg).
          std::size_t end = idx[j] + 1;
          if (excursion_deg > 0.0) {
            double tail_lo = tr.angle_deg[end - 1], tail_hi = tail_lo;
            while (end - 1 > idx[i]) {
              const double th = tr.angle_deg[end - 2];
              if (std::max(tail_hi, th) - std::min(tail_lo, th) >= excursion_deg) break;
              tail_lo = std::min(tail_lo, th);
              tail_hi = std::max(tail_hi, th);
              --end;
            }
          }
          // Stretches inside 0–180° (the simulation's domain).
          const auto [lo, hi] =
              std::minmax_element(tr.angle_deg.begin() + idx[i], tr.angle_deg.begin() + end);
          if (end - idx[i] >= min_n && *lo >= 0.0 && *hi <= 180.0 && *hi - *lo >= excursion_deg) {
            segments.push_back({&tr, idx[i], end});
          }
          i = j + 1;
        }
      }
      return segments;
    };
    // The largest excursion that leaves a stretch: 1, ¾, ½, ¼ of
    // min_segment_excursion_deg, then every stretch.
    std::vector<Segment> segments;
    double excursion_used = 0.0;
    for (const double f : {1.0, 0.75, 0.5, 0.25, 0.0}) {
      excursion_used = f * options.min_segment_excursion_deg;
      segments = find_segments(excursion_used);
      if (!segments.empty() || options.min_segment_excursion_deg <= 0.0) break;
    }
    res.report.values["free_swing_segment_excursion_deg"] = excursion_used;
    if (!segments.empty()) {
      std::vector<SwingStretch> stretches;
      for (const Segment& sg : segments) {
        const TrialColumns& tr = *sg.trial;
        stretches.push_back({tr.angle_deg[sg.begin], tr.velocity_deg_s[sg.begin], tr.SampleRateHz(),
                             std::span(tr.angle_deg).subspan(sg.begin, sg.end - sg.begin)});
      }
      PassiveSwings swings(torque_angle,
                           PiecewiseLinear(bp_v, std::vector<double>(c_b.data(), c_b.data() + mv)),
                           PiecewiseLinear(bp_v, std::vector<double>(c_a.data(), c_a.data() + mv)),
                           std::move(stretches));
      const ScalarMinimum m =
          FitLogInertia(swings, std::log(options.min_inertia_kgm2),
                        std::log(options.max_inertia_kgm2), std::log(p.inertia_kgm2));
      if (std::isfinite(m.cost)) {
        res.report.values["free_swing_inertia_equation_error_kgm2"] = p.inertia_kgm2;
        p.inertia_kgm2 = std::exp(m.x);
        p.torque_velocity = ptv_for(p.inertia_kgm2);
        res.report.fit_rms["free_swing_output_error_deg"] =
            std::sqrt(m.cost / static_cast<double>(swings.samples()));
      }
    }
    res.report.values["free_swing_inertia_segments"] = static_cast<double>(segments.size());
  }
  res.passive = ReferencePassive(p);
  res.report.fit_rms["free_swing_passive_nm"] = sol.rms;
  res.report.values["free_swing_rank"] = sol.rank;
  res.report.values["free_swing_samples"] = static_cast<double>(total);
  if (sol.rank < mv + 1) {
    res.report.warnings.push_back("free-swing passive: rank " + std::to_string(sol.rank) + " of " +
                                  std::to_string(mv + 1) + " parameters (under-determined)");
  }
  for (auto& w :
       SupportWarnings("tau_ptv", "deg/s", bp_v, BreakpointSupport(bp_v, vel), options.min_support))
    res.report.warnings.push_back(std::move(w));
  if (!(p.inertia_kgm2 > 0.0))
    res.report.warnings.push_back("free-swing passive: inertia not positive");
  return res;
}

PassiveResult IdentifyPassiveKnownInertia(std::span<const TrialColumns> trials, double inertia_kgm2,
                                          const BreakpointSpec& angle,
                                          const BreakpointSpec& velocity, double max_activation,
                                          double relative_tolerance) {
  const char* what = "IdentifyPassiveKnownInertia";
  if (!(inertia_kgm2 > 0.0) || !std::isfinite(inertia_kgm2)) {
    throw std::invalid_argument(std::string(what) + ": inertia_kgm2 must be finite and > 0");
  }
  std::vector<double> th, vel, acc;
  for (const TrialColumns& tr : trials) {
    const std::size_t n = tr.t_s.size();
    RequireColumn(what, "angle_deg", tr.angle_deg, n);
    RequireColumn(what, "velocity_deg_s", tr.velocity_deg_s, n);
    RequireColumn(what, "accel_deg_s2", tr.accel_deg_s2, n);
    RequireColumn(what, "activation", tr.activation, n);
    for (std::size_t i = 0; i < n; ++i) {
      if (tr.activation[i] > max_activation) continue;  // §5.4.3: passive samples only
      th.push_back(tr.angle_deg[i]);
      vel.push_back(tr.velocity_deg_s[i]);
      acc.push_back(tr.accel_deg_s2[i]);
    }
  }
  // §7.4.1 with Eq. 4.35: −J·θ̈ = τ_pta(θ) + τ_ptv(θ̇), θ̈ in rad/s².
  const PassiveSystem sys = MakePassiveSystem(what, th, vel, angle, velocity, 0);
  PwlLeastSquares design(sys.bp_a, sys.bp_v, 0, 1, th.size());
  for (std::size_t i = 0; i < th.size(); ++i) {
    const double rhs = -inertia_kgm2 * DegToRad(acc[i]);
    design.AddRow(th[i], vel[i], {}, std::span(&rhs, 1));
  }
  const LeastSquaresSolution sol = SolveTruncatedSvd(design.Reduced(0), relative_tolerance);
  PassiveParams p = PassiveCurves(sys, sol.c);
  p.inertia_kgm2 = inertia_kgm2;
  PassiveResult res;
  res.passive = ReferencePassive(p);
  res.report.fit_rms["free_swing_known_inertia_nm"] = sol.rms;
  res.report.values["free_swing_known_inertia_rank"] = sol.rank;
  res.report.values["free_swing_known_inertia_samples"] = static_cast<double>(th.size());
  // One constant is shared by τ_pta and τ_ptv (§6.5): rank ma + mv − 1 is full.
  const Eigen::Index full = sys.ma + sys.mv - 1;
  if (sol.rank < full) {
    res.report.warnings.push_back("free-swing passive (known J): rank " + std::to_string(sol.rank) +
                                  " of " + std::to_string(full) + " (under-determined)");
  }
  AddSupportWarnings(sys, th, vel, 1.0, res.report);
  return res;
}

}  // namespace fesbench::model
