#include "model/evaluation.h"

#include <algorithm>
#include <boost/math/distributions/students_t.hpp>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "model/units.h"

namespace fesbench::model {
namespace {

void CheckPair(std::string_view what, std::span<const double> prediction,
               std::span<const double> data) {
  if (prediction.size() != data.size()) {
    throw std::invalid_argument(std::string(what) + ": lengths differ (" +
                                std::to_string(prediction.size()) + " vs " +
                                std::to_string(data.size()) + ")");
  }
  if (data.empty()) throw std::invalid_argument(std::string(what) + ": no samples");
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (!std::isfinite(prediction[i]) || !std::isfinite(data[i])) {
      throw std::invalid_argument(std::string(what) + ": non-finite value at sample " +
                                  std::to_string(i));
    }
  }
}

double SumSquaredError(std::span<const double> prediction, std::span<const double> data) {
  double sum = 0.0;
  for (std::size_t i = 0; i < data.size(); ++i) {
    const double e = prediction[i] - data[i];
    sum += e * e;
  }
  return sum;
}

// Slope of a PWL curve on the left of x (segment ending at or after x,
// starting before it); 0 outside the breakpoints, where the curve is held.
double LeftSlope(const PiecewiseLinear& c, double x) {
  const auto& xs = c.x();
  const auto& ys = c.y();
  if (xs.size() < 2 || x <= xs.front() || x > xs.back()) return 0.0;
  const auto hi = static_cast<std::size_t>(std::lower_bound(xs.begin(), xs.end(), x) - xs.begin());
  return (ys[hi] - ys[hi - 1]) / (xs[hi] - xs[hi - 1]);
}

double SlopeAt(const PiecewiseLinear& c, double x, SlopeSide side) {
  switch (side) {
    case SlopeSide::kLeft:
      return LeftSlope(c, x);
    case SlopeSide::kRight:
      return c.Slope(x);
    case SlopeSide::kCentral:
      break;
  }
  return 0.5 * (LeftSlope(c, x) + c.Slope(x));
}

}  // namespace

double RmsError(std::span<const double> prediction, std::span<const double> data) {
  CheckPair("RmsError", prediction, data);
  // Eq. 6.9
  return std::sqrt(SumSquaredError(prediction, data) / static_cast<double>(data.size()));
}

double AbsError(std::span<const double> prediction, std::span<const double> data) {
  CheckPair("AbsError", prediction, data);
  // Eq. 6.10
  double sum = 0.0;
  for (std::size_t i = 0; i < data.size(); ++i) sum += std::abs(prediction[i] - data[i]);
  return sum / static_cast<double>(data.size());
}

std::optional<NormalisedRms> NormalisedRmsError(std::span<const double> prediction,
                                                std::span<const double> data,
                                                double exclude_below_fraction) {
  CheckPair("NormalisedRmsError", prediction, data);
  if (!(exclude_below_fraction >= 0.0 && exclude_below_fraction < 1.0)) {
    throw std::invalid_argument("NormalisedRmsError: exclude_below_fraction must be in [0, 1)");
  }
  double peak = 0.0;
  for (const double d : data) peak = std::max(peak, std::abs(d));
  const double floor = exclude_below_fraction * peak;
  NormalisedRms r;
  double sum = 0.0;
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (std::abs(data[i]) <= floor || data[i] == 0.0) {
      ++r.samples_excluded;
      continue;
    }
    const double rel = (prediction[i] - data[i]) / data[i];  // Eq. 6.1
    sum += rel * rel;
    ++r.samples_used;
  }
  if (r.samples_used == 0) return std::nullopt;  // every sample excluded (data all ~0)
  r.value = std::sqrt(sum / static_cast<double>(r.samples_used));
  return r;
}

std::optional<double> AveragedRmsError(std::span<const double> prediction,
                                       std::span<const double> data) {
  CheckPair("AveragedRmsError", prediction, data);
  double total = 0.0;
  for (const double d : data) total += d;
  if (total == 0.0) return std::nullopt;
  return std::sqrt(SumSquaredError(prediction, data)) / total;  // Eq. 6.2
}

double StudentTCritical(double df, double confidence) {
  if (!(df > 0.0) || !std::isfinite(df)) {
    throw std::invalid_argument("StudentTCritical: df must be positive");
  }
  if (!(confidence > 0.0 && confidence < 1.0)) {
    throw std::invalid_argument("StudentTCritical: confidence must be in (0, 1)");
  }
  const boost::math::students_t dist(df);
  return boost::math::quantile(boost::math::complement(dist, 0.5 * (1.0 - confidence)));
}

PairedTTestResult PairedTTest(std::span<const double> a, std::span<const double> b,
                              double confidence) {
  CheckPair("PairedTTest", a, b);
  if (a.size() < 2) throw std::invalid_argument("PairedTTest: need at least 2 pairs");
  PairedTTestResult r;
  r.n = a.size();
  r.confidence = confidence;
  const double n = static_cast<double>(r.n);
  double mean = 0.0;
  for (std::size_t i = 0; i < r.n; ++i) mean += a[i] - b[i];
  mean /= n;
  double ss = 0.0;
  for (std::size_t i = 0; i < r.n; ++i) {
    const double dev = a[i] - b[i] - mean;
    ss += dev * dev;
  }
  r.mean_difference = mean;
  r.sd_difference = std::sqrt(ss / (n - 1.0));
  if (!(r.sd_difference > 0.0)) {
    throw std::invalid_argument("PairedTTest: all differences are equal (S_d = 0)");
  }
  r.df = n - 1.0;
  r.t = mean / (r.sd_difference / std::sqrt(n));  // Eq. 6.3
  r.t_critical = StudentTCritical(r.df, confidence);
  const boost::math::students_t dist(r.df);
  r.p_value = std::min(1.0, 2.0 * boost::math::cdf(boost::math::complement(dist, std::abs(r.t))));
  r.significant = std::abs(r.t) > r.t_critical;
  return r;
}

PassiveLinearisation LinearisePassive(const PassiveParams& passive, double angle_deg,
                                      double velocity_deg_s, const LinearisationOptions& options) {
  if (passive.torque_angle.empty() || passive.torque_velocity.empty()) {
    throw std::invalid_argument("LinearisePassive: passive curves must not be empty");
  }
  if (!(passive.inertia_kgm2 > 0.0)) {
    throw std::invalid_argument("LinearisePassive: inertia_kgm2 must be positive");
  }
  if (!std::isfinite(angle_deg) || !std::isfinite(velocity_deg_s)) {
    throw std::invalid_argument("LinearisePassive: operating point must be finite");
  }
  PassiveLinearisation r;
  r.angle_deg = angle_deg;
  r.velocity_deg_s = velocity_deg_s;
  // Curves are per degree; the equation of motion is in radians (θ̈ in rad/s²).
  r.stiffness_nm_per_rad =
      SlopeAt(passive.torque_angle, angle_deg, options.angle_side) * kDegPerRad;
  r.damping_nm_s_per_rad =
      SlopeAt(passive.torque_velocity, velocity_deg_s, options.velocity_side) * kDegPerRad;
  if (!(r.stiffness_nm_per_rad > 0.0)) {
    throw std::invalid_argument("LinearisePassive: stiffness at " + std::to_string(angle_deg) +
                                " deg is not positive (" + std::to_string(r.stiffness_nm_per_rad) +
                                " N·m/rad)");
  }
  const double j = passive.inertia_kgm2;
  // J·θ̈ + b·θ̇ + k·θ = 0 → ω_n = √(k/J), ζ = b / (2√(kJ)) (§6.9, Table 6.4).
  r.natural_frequency_rad_s = std::sqrt(r.stiffness_nm_per_rad / j);
  r.damping_ratio = r.damping_nm_s_per_rad / (2.0 * std::sqrt(r.stiffness_nm_per_rad * j));
  if (r.damping_ratio < 1.0) {
    const double root = std::sqrt(1.0 - r.damping_ratio * r.damping_ratio);
    r.damped_period_s = 2.0 * kPi / (r.natural_frequency_rad_s * root);
    r.peak_ratio = std::exp(-kPi * r.damping_ratio / root);
  }
  return r;
}

std::optional<double> FindPassiveRestAngle(const PassiveParams& passive, double hint_deg) {
  if (passive.torque_angle.empty() || passive.torque_velocity.empty()) {
    throw std::invalid_argument("PassiveRestAngle: passive curves must not be empty");
  }
  const auto& xs = passive.torque_angle.x();
  const auto& ys = passive.torque_angle.y();
  const double offset = passive.torque_velocity(0.0);  // τ_ptv(0), see §6.5 referencing
  double best = std::numeric_limits<double>::quiet_NaN();
  auto consider = [&](double root) {
    if (std::isnan(best) || std::abs(root - hint_deg) < std::abs(best - hint_deg)) best = root;
  };
  for (std::size_t i = 0; i + 1 < xs.size(); ++i) {
    const double f0 = ys[i] + offset;
    const double f1 = ys[i + 1] + offset;
    if (f0 == 0.0 && f1 == 0.0) {
      consider(0.5 * (xs[i] + xs[i + 1]));  // flat zero segment: neutrally stable
    } else if (f0 <= 0.0 && f1 > 0.0) {
      // Rising through zero: restoring torque on both sides (stable).
      consider(xs[i] + (xs[i + 1] - xs[i]) * (-f0) / (f1 - f0));
    }
  }
  if (std::isnan(best)) return std::nullopt;
  return best;
}

double PassiveRestAngle(const PassiveParams& passive, double hint_deg) {
  const std::optional<double> rest = FindPassiveRestAngle(passive, hint_deg);
  if (!rest) {
    throw std::invalid_argument(
        "PassiveRestAngle: tau_pta + tau_ptv(0) has no stable zero inside its breakpoints");
  }
  return *rest;
}

}  // namespace fesbench::model
