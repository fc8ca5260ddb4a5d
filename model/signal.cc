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

PulseClock::PulseClock(double rate_hz, double origin_s) : rate_hz_(rate_hz), origin_s_(origin_s) {
  if (!(rate_hz > 0.0) || !std::isfinite(rate_hz)) {
    throw std::invalid_argument("PulseClock: pulse_rate_hz must be finite and > 0");
  }
  if (!std::isfinite(origin_s)) throw std::invalid_argument("PulseClock: origin_s must be finite");
}

std::int64_t PulseClock::FirstAtOrAfter(double t_s) const {
  const double x = (t_s - kPulseTimeToleranceS - origin_s_) * rate_hz_;
  if (!(x > 0.0)) return 0;
  auto k = static_cast<std::int64_t>(std::ceil(x));
  // ceil of a rounded product can be one off either way: settle on TimeOf.
  while (k > 0 && TimeOf(k - 1) >= t_s - kPulseTimeToleranceS) --k;
  while (TimeOf(k) < t_s - kPulseTimeToleranceS) ++k;
  return k;
}

std::optional<double> FirstGridTimeIn(double from_s, double to_s, double pulse_rate_hz) {
  const PulseClock clock(pulse_rate_hz);
  const double t = clock.TimeOf(clock.FirstAtOrAfter(from_s));
  if (t < to_s - kPulseTimeToleranceS) return t;
  return std::nullopt;
}

PulseTrain PulsesFromEnvelope(const SampledSignal& envelope, double pulse_rate_hz) {
  if (!(pulse_rate_hz > 0.0) || !std::isfinite(pulse_rate_hz)) {
    throw std::invalid_argument("PulsesFromEnvelope: pulse rate must be positive");
  }
  if (!(envelope.rate_hz > 0.0) || !std::isfinite(envelope.rate_hz)) {
    throw std::invalid_argument("PulsesFromEnvelope: sample rate must be positive");
  }
  const std::size_t n = envelope.size();
  for (std::size_t k = 0; k < n; ++k) {
    const double v = envelope.values[k];
    if (!std::isfinite(v) || v < 0.0) {
      throw std::invalid_argument("PulsesFromEnvelope: stimulation must be finite and >= 0 (sample " +
                                  std::to_string(k) + ")");
    }
  }
  const PulseClock clock(pulse_rate_hz);
  PulseTrain pulses;
  std::size_t i = 0;
  while (i < n) {
    if (envelope.values[i] == 0.0) {
      ++i;
      continue;
    }
    // A run of non-zero samples [i, j), held over [TimeAt(i), TimeAt(j)).
    std::size_t j = i;
    while (j < n && envelope.values[j] != 0.0) ++j;
    const double start = envelope.TimeAt(i);
    const double end = envelope.TimeAt(j);
    const std::size_t first = pulses.size();
    for (std::int64_t k = clock.FirstAtOrAfter(start);; ++k) {
      const double t = clock.TimeOf(k);
      if (t >= end - kPulseTimeToleranceS) break;
      const double pos =
          std::floor((t - envelope.t0_s + kPulseTimeToleranceS) * envelope.rate_hz);
      const std::size_t idx = std::clamp<std::size_t>(
          pos < 0.0 ? 0 : static_cast<std::size_t>(pos), i, j - 1);
      pulses.push_back({t, envelope.values[idx]});
    }
    if (pulses.size() == first) pulses.push_back({start, envelope.values[i]});  // an impulse
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
