#include "model/signal.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace fesbench::model {

double SampledSignal::HoldAt(double t_s) const {
  if (values.empty() || t_s < t0_s) return 0.0;
  const double k = std::floor((t_s - t0_s) * rate_hz + 1e-9);
  if (k >= static_cast<double>(values.size())) return 0.0;
  return values[static_cast<std::size_t>(k)];
}

double SampledSignal::InterpolateAt(double t_s) const {
  if (values.empty()) throw std::invalid_argument("InterpolateAt: empty signal");
  const double pos = (t_s - t0_s) * rate_hz;
  if (pos <= 0.0) return values.front();
  const double last = static_cast<double>(values.size() - 1);
  if (pos >= last) return values.back();
  const auto i = static_cast<std::size_t>(pos);
  const double w = pos - static_cast<double>(i);
  return (1.0 - w) * values[i] + w * values[i + 1];
}

PulseTrain PulsesFromEnvelope(const SampledSignal& envelope, double pulse_rate_hz) {
  if (!(pulse_rate_hz > 0.0) || !std::isfinite(pulse_rate_hz)) {
    throw std::invalid_argument("PulsesFromEnvelope: pulse rate must be positive");
  }
  if (!(envelope.rate_hz > 0.0)) {
    throw std::invalid_argument("PulsesFromEnvelope: sample rate must be positive");
  }
  const double period_s = 1.0 / pulse_rate_hz;
  PulseTrain pulses;
  std::size_t i = 0;
  const std::size_t n = envelope.size();
  for (std::size_t k = 0; k < n; ++k) {
    const double v = envelope.values[k];
    if (!std::isfinite(v) || v < 0.0) {
      throw std::invalid_argument("PulsesFromEnvelope: stimulation must be finite and >= 0 (sample " +
                                  std::to_string(k) + ")");
    }
  }
  while (i < n) {
    if (envelope.values[i] == 0.0) {
      ++i;
      continue;
    }
    // A run of non-zero samples [i, j): pulses at its onset and every period.
    std::size_t j = i;
    while (j < n && envelope.values[j] != 0.0) ++j;
    const double start = envelope.TimeAt(i);
    const double end = envelope.TimeAt(j);
    for (int m = 0;; ++m) {
      const double t = start + m * period_s;
      if (t >= end - 1e-12) break;
      const auto idx = std::min(
          j - 1, i + static_cast<std::size_t>(std::floor((t - start) * envelope.rate_hz + 1e-9)));
      pulses.push_back({t, envelope.values[idx]});
    }
    i = j;
  }
  return pulses;
}

SampledTrajectory::SampledTrajectory(double rate_hz, std::vector<double> angle_deg,
                                     std::vector<double> velocity_deg_s,
                                     std::vector<double> accel_deg_s2) {
  if (!(rate_hz > 0.0) || !std::isfinite(rate_hz)) {
    throw std::invalid_argument("SampledTrajectory: rate must be positive");
  }
  if (angle_deg.empty()) throw std::invalid_argument("SampledTrajectory: no samples");
  if (velocity_deg_s.size() != angle_deg.size() || accel_deg_s2.size() != angle_deg.size()) {
    throw std::invalid_argument("SampledTrajectory: columns differ in length");
  }
  for (const auto* col : {&angle_deg, &velocity_deg_s, &accel_deg_s2}) {
    if (!std::all_of(col->begin(), col->end(), [](double v) { return std::isfinite(v); })) {
      throw std::invalid_argument("SampledTrajectory: non-finite sample");
    }
  }
  angle_ = {rate_hz, 0.0, std::move(angle_deg)};
  velocity_ = {rate_hz, 0.0, std::move(velocity_deg_s)};
  accel_ = {rate_hz, 0.0, std::move(accel_deg_s2)};
}

Kinematics SampledTrajectory::At(double t_s) const {
  return {angle_.InterpolateAt(t_s), velocity_.InterpolateAt(t_s), accel_.InterpolateAt(t_s)};
}

double SampledTrajectory::duration_s() const {
  return static_cast<double>(angle_.size() - 1) / angle_.rate_hz;
}

}  // namespace fesbench::model
