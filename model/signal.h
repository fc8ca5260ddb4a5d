#pragma once

/// @file
/// Time signals shared by generators, simulation and identification:
/// uniformly sampled signals (the 200 Hz stimulation envelope the
/// clinician sees), the stimulator's pulse train (what the muscle receives,
/// DESIGN.md §3) and prescribed knee trajectories (motor mode, §4.2.2).

#include <cstddef>
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

/// The pulses a stimulator triggered by a sampled amplitude envelope
/// (stim_ma) delivers: a pulse at the start of every run of non-zero
/// samples, then one every 1 / pulse_rate_hz while the envelope stays
/// non-zero, each with the envelope's held amplitude at its time. A single
/// non-zero sample therefore gives exactly one pulse (an impulse, §4.1.2),
/// and a burst gives a train at the pulse rate (33 Hz, §5.1).
/// @throws std::invalid_argument if pulse_rate_hz <= 0 or any value is
///   negative or not finite.
PulseTrain PulsesFromEnvelope(const SampledSignal& envelope_ma, double pulse_rate_hz);

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
