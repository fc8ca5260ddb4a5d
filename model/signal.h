#pragma once

/// @file
/// Time signals shared by generators, simulation and identification:
/// uniformly sampled signals (the 200 Hz stimulation envelope the
/// clinician sees), the stimulator's pulse train (what the muscle receives,
/// docs/MODEL.md) and prescribed knee trajectories (motor mode, §4.2.2).

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

namespace fesbench::model {

/// A uniformly sampled signal: value[i] at t0_s + i / rate_hz.
struct SampledSignal {
  double rate_hz = 200.0;
  double t0_s = 0.0;
  std::vector<double> values;

  std::size_t size() const { return values.size(); }
  double TimeAt(std::size_t i) const { return t0_s + static_cast<double>(i) / rate_hz; }
  /// Time just after the last sample (t0 + N / rate).
  double EndTime() const { return t0_s + static_cast<double>(values.size()) / rate_hz; }
  /// Sample-and-hold value at t (0 before the first sample and from
  /// EndTime() on), as a stimulator's D/A holds its last set-point.
  double HoldAt(double t_s) const;
  /// Linear interpolation at t, end values held outside.
  /// @throws std::invalid_argument if the signal is empty.
  double InterpolateAt(double t_s) const;
};

/// One stimulation pulse: an impulse of amplitude stim_ma at t_s.
struct Pulse {
  double t_s = 0.0;
  double stim_ma = 0.0;
  friend bool operator==(const Pulse&, const Pulse&) = default;
};

/// Pulses in strictly increasing time.
using PulseTrain = std::vector<Pulse>;

/// Two times closer than this are the same instant of the pulse clock, s
/// (absorbs the round-off of origin + k / f on a bench clock).
inline constexpr double kPulseTimeToleranceS = 1e-9;

/// The stimulator's pulse clock (docs/MODEL.md, one rule for bench, model,
/// CLI, predictions and the model gate): it runs continuously from its
/// origin — the start of a trial — and offers a pulse at every grid time
/// t_k = origin_s + k / rate_hz, k = 0, 1, …; the amplitude envelope decides
/// whether a grid time fires (amplitude > 0) and with what amplitude. A
/// burst therefore does not restart the grid.
class PulseClock {
 public:
  /// @throws std::invalid_argument unless rate_hz is finite and > 0 and
  ///   origin_s is finite.
  explicit PulseClock(double rate_hz, double origin_s = 0.0);

  double rate_hz() const { return rate_hz_; }
  double origin_s() const { return origin_s_; }
  /// Grid time k, s: origin_s + k / rate_hz (computed as a division so that
  /// k / f is exact wherever it can be, e.g. 132 / 33 = 4).
  double TimeOf(std::int64_t k) const {
    return origin_s_ + static_cast<double>(k) / rate_hz_;
  }
  /// The smallest k ≥ 0 with TimeOf(k) ≥ t_s − kPulseTimeToleranceS.
  std::int64_t FirstAtOrAfter(double t_s) const;

 private:
  double rate_hz_;
  double origin_s_;
};

/// The pulses a stimulator with a continuous pulse clock delivers for a
/// sampled amplitude envelope (stim_ma held from each sample to the next, as
/// a D/A holds its set-point), with the clock's origin at t = 0 of the
/// envelope's time axis (the trial's start; envelope.t0_s is the time of its
/// first sample on that axis):
///  - every grid time t_k = k / pulse_rate_hz at which the held envelope is
///    non-zero is a pulse with that amplitude (a burst fires on the grid; its
///    first pulse is at the first grid time inside it, not at its onset);
///  - a run of non-zero samples that holds no grid time (shorter than one
///    pulse period and between two grid times, e.g. a single 5 ms sample:
///    an impulse, §4.1.2) is one single pulse at the run's first sample with
///    that sample's amplitude — the stimulator's single-pulse command, which
///    the protocol runner issues for such a run (Bench::TriggerPulse).
/// So an isolated impulse is exactly one pulse, however the envelope was
/// sampled, and a train at amplitude u is a 33 Hz train on the trial's grid.
/// @throws std::invalid_argument if pulse_rate_hz or the envelope's rate is
///   not finite and > 0, or any value is negative or not finite.
PulseTrain PulsesFromEnvelope(const SampledSignal& envelope_ma, double pulse_rate_hz);

/// The first grid time of a pulse clock with origin 0 in [from_s, to_s)
/// (both within kPulseTimeToleranceS), if any: the test PulsesFromEnvelope
/// applies to a run of non-zero samples, shared with the protocol runner.
/// @throws std::invalid_argument as PulseClock.
std::optional<double> FirstGridTimeIn(double from_s, double to_s, double pulse_rate_hz);

/// Knee kinematics at one instant.
struct Kinematics {
  double angle_deg = 0.0;
  double velocity_deg_s = 0.0;
  double accel_deg_s2 = 0.0;
};

/// A prescribed knee trajectory θ(t) with its derivatives (motor mode).
class Trajectory {
 public:
  virtual ~Trajectory() = default;
  virtual Kinematics At(double t_s) const = 0;
  virtual double duration_s() const = 0;
};

/// A trajectory given as samples of angle, velocity and acceleration at a
/// fixed rate (e.g. read from a CSV file); linear interpolation between
/// samples, end values held outside.
class SampledTrajectory final : public Trajectory {
 public:
  /// @throws std::invalid_argument if the columns differ in length, are
  ///   empty, hold non-finite values, or rate_hz <= 0.
  SampledTrajectory(double rate_hz, std::vector<double> angle_deg,
                    std::vector<double> velocity_deg_s, std::vector<double> accel_deg_s2);
  Kinematics At(double t_s) const override;
  double duration_s() const override;

 private:
  SampledSignal angle_, velocity_, accel_;
};

}  // namespace fesbench::model
