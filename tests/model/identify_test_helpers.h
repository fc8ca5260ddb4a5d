#pragma once

/// @file
/// Set-up shared by the identification tests: simulated trials as the
/// TrialColumns the identification methods take.

#include <optional>

#include "model/contraction.h"
#include "model/identify_common.h"
#include "model/parameter_set.h"
#include "model/signal.h"
#include "model/simulate.h"

namespace fesbench::model::test_helpers {

/// Whether the simulator's activation is copied into the columns.
enum class Activation { kCopy, kLeaveOut };

/// The channels of `sim` as identification columns. With kLeaveOut the
/// activation column stays empty (for tests that recompute it from an
/// identified model, as the lab must).
inline TrialColumns ColumnsOf(const SimulationResult& sim,
                              Activation activation = Activation::kCopy) {
  TrialColumns tr;
  tr.t_s = sim.t_s;
  tr.stim_ma = sim.stim_ma;
  tr.angle_deg = sim.angle_deg;
  tr.velocity_deg_s = sim.velocity_deg_s;
  tr.accel_deg_s2 = sim.accel_deg_s2;
  tr.torque_nm = sim.torque_nm;
  if (activation == Activation::kCopy) tr.activation = sim.activation;
  return tr;
}

/// Simulation options that run for the whole stimulus envelope `env`,
/// optionally simulating another model kind than the parameter set's.
inline SimulationOptions WholeEnvelope(const SampledSignal& env,
                                       std::optional<ModelKind> kind = {}) {
  SimulationOptions o;
  o.duration_s = env.EndTime();
  o.model_kind = kind;
  return o;
}

/// A free swing of `p` under envelope `env` at the default pulse rate, as
/// columns with the simulator's activation.
inline TrialColumns SimulatedFreeSwing(const ParameterSet& p, const SampledSignal& env,
                                       std::optional<ModelKind> kind = {}) {
  return ColumnsOf(
      SimulateFreeSwing(p, PulsesFromEnvelope(env, kDefaultPulseRateHz), WholeEnvelope(env, kind)));
}

}  // namespace fesbench::model::test_helpers
