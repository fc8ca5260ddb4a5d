#pragma once

/// @file
/// The strength state (model/strength.h; docs/MODEL.md, "Strength that
/// changes with use", "The strength at a trial's start") driven by the
/// pulses that were delivered: through one trial, and through a session's
/// trials and the rests between them to a later trial's start.
///
/// The activation a pulse train asks for is piecewise constant: pulse k at
/// t_k of amplitude u_k holds f = R(u_k) (the IRC, Eq. 3.1: the mean f_stim of
/// a steady train at u_k) from t_k for one pulse period 1/f_pulse, or until
/// the next pulse if that comes sooner; f = 0 otherwise. The adaptive
/// controller's rule (model/tracking.h) written per pulse: a steady train
/// is f = R(u) throughout, a single pulse one period of it. Each piece is
/// propagated exactly (StrengthModel::Propagate).

#include <optional>
#include <vector>

#include "model/contraction.h"
#include "model/piecewise_linear.h"
#include "model/signal.h"
#include "model/strength.h"

namespace fesbench::model {

/// s(t) through one pulse train from a given state at t = 0.
class StrengthTrace {
 public:
  /// `pulses` as model::ValidatePulseTrain accepts them (times ≥ 0,
  /// increasing); `irc` gives R(u).
  /// @throws std::invalid_argument for a pulse rate that is not finite and
  ///   > 0, or pulses with non-finite times.
  StrengthTrace(const StrengthModel& model, const PiecewiseLinear& irc, const PulseTrain& pulses,
                double pulse_rate_hz, StrengthState initial = {});

  /// The state at t_s ≥ 0 (t_s < 0 reads the initial state).
  StrengthState At(double t_s) const;
  /// StrengthFactor(At(t_s)).
  double FactorAt(double t_s) const { return StrengthFactor(At(t_s)); }
  /// The end of the last pulse's period (0 without pulses): from here on
  /// the train asks for nothing.
  double end_s() const { return end_s_; }
  /// Σ R(u_k)·s(t_k) / Σ R(u_k) over the pulses: the strength the train's
  /// torque saw on average, weighted by what each pulse asks for; unset if
  /// no pulse asks for anything.
  std::optional<double> ActivationWeightedFactor() const;

 private:
  const StrengthModel* model_;
  // Breakpoints: from t_[j] on the activation is f_[j] and the state
  // starts at s_[j].
  std::vector<double> t_;
  std::vector<double> f_;
  std::vector<StrengthState> s_;
  std::vector<double> pulse_t_, pulse_f_;
  double end_s_ = 0.0;
};

/// A stimulation record of a session: a trial's start on the session's
/// clock and the pulses it delivered (times from its start).
struct StimulationRecord {
  double start_s = 0.0;
  PulseTrain pulses;
  double pulse_rate_hz = kDefaultPulseRateHz;
};

/// The strength state at `at_s` on the session's clock, from `initial` before
/// the first record: each record's pulses (StrengthTrace) from its start,
/// cut at `at_s`, and rest (f = 0) in between. Records are taken in order of
/// start; a record starting before the previous one's pulses end starts
/// when they end (no pulse is counted twice). Records starting at or after
/// `at_s` are ignored.
/// @throws std::invalid_argument as StrengthTrace, or for non-finite times.
StrengthState StrengthAtStart(const StrengthModel& model, const PiecewiseLinear& irc,
                              std::vector<StimulationRecord> history, double at_s,
                              StrengthState initial = {});

}  // namespace fesbench::model
