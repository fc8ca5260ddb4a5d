#include "model/daily_check.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "model/identify_isometric.h"
#include "model/inverse_model.h"
#include "model/joint_model.h"

namespace fesbench::model {
namespace {

// Threshold and slope of a recruitment curve (inverse at R = 0.1 and 0.9).
void RecruitmentShape(const PiecewiseLinear& irc, LegSignature& s) {
  const double lo = InverseRecruitment(irc, 0.1), hi = InverseRecruitment(irc, 0.9);
  s.threshold_ma = lo;
  s.slope_per_ma = hi > lo ? 0.8 / (hi - lo) : 0.0;
}

// Sample standard deviation of the finite values (0 for fewer than two).
double Spread(const std::vector<double>& v) {
  if (v.size() < 2) return 0.0;
  double mean = 0.0;
  for (double x : v) mean += x;
  mean /= static_cast<double>(v.size());
  double ss = 0.0;
  for (double x : v) ss += (x - mean) * (x - mean);
  return std::sqrt(ss / static_cast<double>(v.size() - 1));
}

}  // namespace

PiecewiseLinear MovedRecruitment(const PiecewiseLinear& irc, double threshold_ma, double shift_ma,
                                 double stretch) {
  std::vector<double> x = irc.x();
  for (double& u : x) u = threshold_ma + shift_ma + (u - threshold_ma) * stretch;
  return PiecewiseLinear(std::move(x), irc.y());
}

RecruitmentMove FitRecruitmentMove(const PiecewiseLinear& before, double before_scale_nm,
                                   double before_threshold_ma, const PiecewiseLinear& today,
                                   double today_scale_nm) {
  constexpr int kSamples = 100;
  const double u_hi = today.x().back();
  const double before_hi = before.x().back();
  const bool before_saturated = before.y().back() >= 0.99;
  std::vector<double> u(kSamples), t1(kSamples), t0(kSamples);
  double peak = 0.0;
  for (int i = 0; i < kSamples; ++i) {
    u[i] = u_hi * (i + 0.5) / kSamples;
    t1[i] = today_scale_nm * today(u[i]);
    peak = std::max(peak, std::abs(t1[i]));
  }
  if (!(peak > 0.0)) throw std::invalid_argument("today's ramp gives no torque");
  struct Fit {
    double cost = std::numeric_limits<double>::infinity(), gain = 1.0;
  };
  const auto fit = [&](double shift, double stretch) {
    double st0 = 0.0, s00 = 0.0, s11 = 0.0;
    int n = 0;
    for (int i = 0; i < kSamples; ++i) {
      const double v = before_threshold_ma + (u[i] - before_threshold_ma - shift) / stretch;
      if (v > before_hi && !before_saturated) continue;
      const double b = before_scale_nm * before(std::max(v, 0.0));
      st0 += t1[i] * b;
      s00 += b * b;
      s11 += t1[i] * t1[i];
      ++n;
    }
    Fit f;
    if (n < 10 || !(s00 > 0.0)) return f;
    f.gain = st0 / s00;
    f.cost = std::max(0.0, s11 - f.gain * st0) / n;  // Σ(t1 − g·t0)² at the optimal g
    return f;
  };
  RecruitmentMove out;
  double best = std::numeric_limits<double>::infinity(), best_shift_only =
      std::numeric_limits<double>::infinity();
  for (int j = 0; j <= 50; ++j) {
    const double stretch = 0.6 + 0.02 * j;
    for (int i = -320; i <= 320; ++i) {
      const double shift = 0.025 * i;
      const Fit f = fit(shift, stretch);
      if (f.cost < best) {
        best = f.cost;
        out.shift_ma = shift;
        out.stretch = stretch;
        out.gain = f.gain;
      }
      if (j == 20 && f.cost < best_shift_only) {  // stretch 1
        best_shift_only = f.cost;
        out.shift_only_ma = shift;
        out.shift_only_gain = f.gain;
      }
    }
  }
  if (!std::isfinite(best)) {
    throw std::invalid_argument("too few of today's amplitudes were tested before");
  }
  out.misfit = std::sqrt(best) / peak;
  out.shift_only_misfit = std::sqrt(best_shift_only) / peak;
  return out;
}

std::string_view DailyVerdictName(DailyVerdict verdict) {
  switch (verdict) {
    case DailyVerdict::kNoChange:
      return "no_change";
    case DailyVerdict::kRefit:
      return "refit";
    case DailyVerdict::kRapidDue:
      return "rapid_due";
  }
  return "no_change";
}

LegSignature SignatureOfSet(const ParameterSet& set, double lock_angle_deg) {
  const JointModel joint = JointModel::FromParameters(set);
  LegSignature s;
  RecruitmentShape(set.irc, s);
  s.full_scale_nm = joint.ActiveGain(lock_angle_deg, 0.0);
  s.pole_per_s = set.contraction.pole_per_s;
  return s;
}

LegSignature SignatureOfTrial(const TrialColumns& ramp_trial, int order, PiecewiseLinear* irc) {
  const TrialColumns trials[] = {ramp_trial};
  ContractionOptions contraction;
  contraction.order = order;
  const ContractionResult c = IdentifyContraction(trials, contraction);
  const IrcResult r = IdentifyIrc(IrcMethod::kRampCorrelation, ramp_trial);
  LegSignature s;
  RecruitmentShape(r.irc, s);
  s.full_scale_nm = r.torque_scale_nm;
  s.pole_per_s = c.contraction.pole_per_s;
  if (irc != nullptr) *irc = r.irc;
  return s;
}

DailyCheck CompareDaily(const ParameterSet& stored, const TrialColumns& ramp_trial,
                        double lock_angle_deg, std::span<const ParameterSet> history,
                        const TrialColumns* base_ramp, const DriftFloors& floors) {
  const LegSignature own = SignatureOfSet(stored, lock_angle_deg);
  PiecewiseLinear base_irc = stored.irc;
  const LegSignature was =
      base_ramp != nullptr ? SignatureOfTrial(*base_ramp, stored.contraction.order, &base_irc) : own;
  PiecewiseLinear today_irc;
  const LegSignature measured = SignatureOfTrial(ramp_trial, stored.contraction.order, &today_irc);
  // Threshold, slope and full scale from one fit of today's torque curve to
  // the earlier one, where both were measured.
  const RecruitmentMove move = FitRecruitmentMove(base_irc, was.full_scale_nm, was.threshold_ma,
                                                  today_irc, measured.full_scale_nm);
  LegSignature now = measured;
  // §7.6.4: the leg's own spread from set to set sets the bounds.
  std::vector<double> thresholds, slopes, scales, poles;
  for (const ParameterSet& h : history) {
    try {
      const LegSignature s = SignatureOfSet(h, lock_angle_deg);
      thresholds.push_back(s.threshold_ma);
      slopes.push_back(s.slope_per_ma / own.slope_per_ma);
      scales.push_back(s.full_scale_nm / own.full_scale_nm);
      poles.push_back(s.pole_per_s / own.pole_per_s);
    } catch (const std::invalid_argument&) {
      continue;  // an unusable old set teaches nothing about the spread
    }
  }
  const bool learned = thresholds.size() >= 3;
  const auto bound = [&](double floor, const std::vector<double>& v) {
    return learned ? std::max(floor, floors.sigmas * Spread(v)) : floor;
  };
  DailyCheck out;
  const auto add = [&](const char* name, double stored_value, double today_value, bool absolute,
                       double b) {
    Drift d;
    d.name = name;
    d.stored = stored_value;
    d.today = today_value;
    d.change = absolute ? today_value - stored_value
                        : (stored_value != 0.0 ? today_value / stored_value - 1.0 : 0.0);
    d.bound = b;
    d.moved = !(std::abs(d.change) <= b);
    out.drifts.push_back(d);
    return d.moved;
  };
  // The stretch counts only beyond the slope's bound; within it today's
  // curve is the earlier one shifted and scaled.
  const double slope_bound = bound(floors.slope_fraction, slopes);
  const bool stretched = !(std::abs(1.0 / move.stretch - 1.0) <= slope_bound);
  const double shift = stretched ? move.shift_ma : move.shift_only_ma;
  const double stretch = stretched ? move.stretch : 1.0;
  const double misfit = stretched ? move.misfit : move.shift_only_misfit;
  now.threshold_ma = was.threshold_ma + shift;
  now.slope_per_ma = was.slope_per_ma / move.stretch;
  now.full_scale_nm = was.full_scale_nm * (stretched ? move.gain : move.shift_only_gain);
  const bool threshold = add("irc_threshold_ma", was.threshold_ma, now.threshold_ma, true,
                             bound(floors.threshold_ma, thresholds));
  const bool slope = add("irc_slope", was.slope_per_ma, now.slope_per_ma, false, slope_bound);
  const bool scale = add("full_scale", was.full_scale_nm, now.full_scale_nm, false,
                         bound(floors.full_scale_fraction, scales));
  const bool pole =
      add("pole", was.pole_per_s, now.pole_per_s, false, bound(floors.pole_fraction, poles));

  out.recruitment_misfit = misfit;
  std::ostringstream why;
  if (pole) {
    out.verdict = DailyVerdict::kRapidDue;
    why << "the contraction pole moved " << 100.0 * out.drifts[3].change
        << " %: every active curve depends on it, a full rapid_parameterisation run is due";
  } else if (!(misfit <= floors.recruitment_misfit)) {
    out.verdict = DailyVerdict::kRapidDue;
    why << "today's recruitment is not the stored one moved (what a shift, stretch and gain "
           "leave unexplained is "
        << 100.0 * misfit << " % of the torque): a full rapid_parameterisation run is due";
  } else if (threshold || slope || scale) {
    out.verdict = DailyVerdict::kRefit;
    ParameterSet updated = stored;
    if (threshold || slope) {
      updated.irc = MovedRecruitment(stored.irc, own.threshold_ma, shift, stretch);
      out.refitted.push_back("irc");
    }
    if (scale) {
      updated.active.torque_scale_nm *= now.full_scale_nm / was.full_scale_nm;
      out.refitted.push_back("torque_scale");
    }
    why << "re-fitted";
    for (const std::string& r : out.refitted) why << " " << r;
    why << " from today's ramp trial; the rest kept";
    updated.provenance.warnings.push_back("daily check: " + why.str());
    out.updated = std::move(updated);
  } else {
    out.verdict = DailyVerdict::kNoChange;
    why << "no parameter moved beyond its bound: the stored set stands";
  }
  if (!learned) why << " (bounds: the floors; the leg has fewer than three sets)";
  out.summary = why.str();
  return out;
}

}  // namespace fesbench::model
