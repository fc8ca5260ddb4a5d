#include "model/daily_check.h"

#include <algorithm>
#include <cmath>
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
  const LegSignature was =
      base_ramp != nullptr ? SignatureOfTrial(*base_ramp, stored.contraction.order, nullptr) : own;
  PiecewiseLinear today_irc;
  const LegSignature now = SignatureOfTrial(ramp_trial, stored.contraction.order, &today_irc);
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
  const bool threshold = add("irc_threshold_ma", was.threshold_ma, now.threshold_ma, true,
                             bound(floors.threshold_ma, thresholds));
  const bool slope = add("irc_slope", was.slope_per_ma, now.slope_per_ma, false,
                         bound(floors.slope_fraction, slopes));
  const bool scale = add("full_scale", was.full_scale_nm, now.full_scale_nm, false,
                         bound(floors.full_scale_fraction, scales));
  const bool pole =
      add("pole", was.pole_per_s, now.pole_per_s, false, bound(floors.pole_fraction, poles));

  std::ostringstream why;
  if (pole) {
    out.verdict = DailyVerdict::kRapidDue;
    why << "the contraction pole moved " << 100.0 * out.drifts[3].change
        << " %: every active curve depends on it, a full rapid_parameterisation run is due";
  } else if (threshold || slope || scale) {
    out.verdict = DailyVerdict::kRefit;
    ParameterSet updated = stored;
    if (threshold || slope) {
      updated.irc = today_irc;
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
