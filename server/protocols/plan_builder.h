#pragma once

/// @file
/// The generic step builders every protocol's plan is made of
/// (docs/PROTOCOLS.md; docs/ARCHITECTURE.md, protocols): preparation, the
/// 50-sample offset (§5.3), rests, recorded stimulation envelopes and motor
/// moves. A protocol class (protocol_registry.h) composes them; plan.cc
/// implements them and knows no protocol.

#include <cstdint>
#include <initializer_list>
#include <memory>
#include <string>

#include "model/signal.h"
#include "model/stimulus_generators.h"
#include "model/trajectory.h"
#include "server/protocols/plan.h"

namespace fesbench::server::protocols {

/// Whole control ticks (1 ms) of a duration in seconds, rounded.
std::int64_t Ticks(double s);

/// The values of `names` that `values` holds, as a generator's parameters.
model::GeneratorParams Pick(const ParameterValues& values,
                            std::initializer_list<const char*> names);

/// A dense or sparse random-binary train (model/stimulus_generators.h).
model::SampledSignal RandomBinary(bool dense, double amplitude_ma, double duration_s, double seed);

/// Appends trials and steps to a plan; a step of no ticks is dropped.
class PlanBuilder {
 public:
  explicit PlanBuilder(Plan& plan) : plan_(plan) {}

  Plan& plan() { return plan_; }

  /// A trial the plan records; its index.
  int AddTrial(std::string name, MotorMode mode, bool setpoint = false);

  /// Moves to or locks at angle_deg for settle_s (not recorded).
  void Prepare(std::string label, MotorMode mode, double angle_deg, double settle_s,
               bool move_from_current = false);

  /// The 50-sample offset that starts a trial (§5.3).
  void Offset(int trial, MotorMode mode, double angle_deg);

  /// A rest of rest_s, never shorter than min_rest_s.
  void Rest(std::string label, double rest_s, double min_rest_s, int trial, MotorMode mode,
            double angle_deg);

  /// A recorded stimulation envelope: the offset lead, then its runs of
  /// stimulation (kStimulate) and of zero (kRest, whose last 50 ms before
  /// the next stimulation is a fresh torque offset, kOffset).
  void EnvelopeTrial(int trial, const model::SampledSignal& envelope, MotorMode mode,
                     double angle_deg, double min_rest_s);

  /// The motor follows trajectory (recorded to trial).
  void Move(std::string label, std::shared_ptr<const model::Trajectory> trajectory, int trial);

  /// A minimum-jerk move from where the knee is to angle_deg in move_s.
  void MoveTo(std::string label, double angle_deg, double move_s, int trial);

  void Push(Step step);

 private:
  Plan& plan_;
};

}  // namespace fesbench::server::protocols
