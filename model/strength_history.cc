#include "model/strength_history.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace fesbench::model {

StrengthTrace::StrengthTrace(const StrengthModel& model, const PiecewiseLinear& irc,
                             const PulseTrain& pulses, double pulse_rate_hz, StrengthState initial)
    : model_(&model) {
  if (!std::isfinite(pulse_rate_hz) || !(pulse_rate_hz > 0.0)) {
    throw std::invalid_argument("strength: pulse_rate_hz must be finite and > 0");
  }
  const double period_s = 1.0 / pulse_rate_hz;
  t_.reserve(2 * pulses.size() + 1);
  f_.reserve(2 * pulses.size() + 1);
  s_.reserve(2 * pulses.size() + 1);
  pulse_t_.reserve(pulses.size());
  pulse_f_.reserve(pulses.size());
  t_.push_back(0.0);
  f_.push_back(0.0);
  s_.push_back(initial);
  // Appends a breakpoint at `t` with activation `f` after it.
  const auto add = [&](double t, double f) {
    if (t <= t_.back()) {  // same instant: the later activation holds
      f_.back() = f;
      return;
    }
    s_.push_back(model.Propagate(s_.back(), f_.back(), t - t_.back()));
    t_.push_back(t);
    f_.push_back(f);
  };
  for (std::size_t k = 0; k < pulses.size(); ++k) {
    const double tk = pulses[k].t_s;
    if (!std::isfinite(tk)) throw std::invalid_argument("strength: pulse times must be finite");
    const double f = pulses[k].stim_ma > 0.0 ? std::clamp(irc(pulses[k].stim_ma), 0.0, 1.0) : 0.0;
    add(std::max(tk, 0.0), f);
    pulse_t_.push_back(std::max(tk, 0.0));
    pulse_f_.push_back(f);
    const double off = tk + period_s;
    if (k + 1 == pulses.size() || pulses[k + 1].t_s > off) {
      add(off, 0.0);
      end_s_ = off;
    } else {
      end_s_ = std::max(end_s_, off);
    }
  }
}

StrengthState StrengthTrace::At(double t_s) const {
  if (!(t_s > 0.0)) return s_.front();
  // The last breakpoint at or before t_s.
  const auto it = std::upper_bound(t_.begin(), t_.end(), t_s);
  const auto j = static_cast<std::size_t>(it - t_.begin()) - 1;
  return model_->Propagate(s_[j], f_[j], t_s - t_[j]);
}

std::optional<double> StrengthTrace::ActivationWeightedFactor() const {
  double sf = 0.0, sum_f = 0.0;
  for (std::size_t k = 0; k < pulse_t_.size(); ++k) {
    sf += pulse_f_[k] * FactorAt(pulse_t_[k]);
    sum_f += pulse_f_[k];
  }
  if (!(sum_f > 0.0)) return std::nullopt;
  return sf / sum_f;
}

StrengthState StrengthAtStart(const StrengthModel& model, const PiecewiseLinear& irc,
                              std::vector<StimulationRecord> history, double at_s,
                              StrengthState initial) {
  if (!std::isfinite(at_s)) throw std::invalid_argument("strength: the start time must be finite");
  for (const StimulationRecord& r : history) {
    if (!std::isfinite(r.start_s)) {
      throw std::invalid_argument("strength: record start times must be finite");
    }
  }
  std::stable_sort(history.begin(), history.end(),
                   [](const StimulationRecord& a, const StimulationRecord& b) {
                     return a.start_s < b.start_s;
                   });
  StrengthState s = initial;
  bool started = false;
  double t = 0.0;  // the session time `s` is at
  for (const StimulationRecord& r : history) {
    if (r.start_s >= at_s) break;
    const double start = started ? std::max(r.start_s, t) : r.start_s;
    if (started && start > t) s = model.Propagate(s, 0.0, start - t);
    // A record moved to a later `start` loses its pulses before it.
    const double shift = start - r.start_s;
    PulseTrain moved;
    if (shift > 0.0) {
      for (const Pulse& p : r.pulses) {
        if (p.t_s >= shift) moved.push_back({p.t_s - shift, p.stim_ma});
      }
    }
    const StrengthTrace trace(model, irc, shift > 0.0 ? moved : r.pulses, r.pulse_rate_hz, s);
    const double until = std::min(trace.end_s(), at_s - start);
    if (until > 0.0) s = trace.At(until);
    t = start + std::max(until, 0.0);
    started = true;
  }
  if (started && at_s > t) s = model.Propagate(s, 0.0, at_s - t);
  return s;
}

}  // namespace fesbench::model
