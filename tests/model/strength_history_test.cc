// The strength state through a session's history and in the simulation
// (docs/MODEL.md, "The strength at a trial's start"): a steady train of known
// length then a rest against the written-out solution of model/strength.h's
// equations, and the simulation's strength factor against a set whose
// τ_scale holds it.
#include "model/strength_history.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "model/simulate.h"

namespace fesbench::model {
namespace {

// R(u) = u / 100 mA: a train at 50 mA asks for f = 0.5.
PiecewiseLinear LinearIrc() { return PiecewiseLinear({0.0, 100.0}, {0.0, 1.0}); }

// n pulses of `stim_ma` at 33 Hz from t = 0: f constant for n / 33 s.
PulseTrain SteadyTrain(int n, double stim_ma) {
  PulseTrain pulses;
  for (int k = 0; k < n; ++k) pulses.push_back({k / 33.0, stim_ma});
  return pulses;
}

TEST(StrengthHistoryTest, SteadyTrainThenRestIsTheWrittenOutSolution) {
  // Riener's form with potentiation: after a 10 s train at f = 0.5 that
  // starts at 5 s, 30 s of rest to the next trial's start at 45 s.
  StrengthParameters p = StrengthParameters::RienerPrior();
  p.potentiation_max = 0.3;
  p.potentiation_time_s = 2.0;
  p.potentiation_decay_s = 60.0;
  const StrengthModel m(p);
  const double f = 0.5, train_s = 10.0, rest_s = 30.0;
  // The train: dx/dt = a − b·x, x(0) = 1; dP/dt = a_p − b_p·P, P(0) = 0.
  const double a = p.min_fitness * f / p.fatigue_time_s + (1.0 - f) / p.recovery_time_s;
  const double b = f / p.fatigue_time_s + (1.0 - f) / p.recovery_time_s;
  const double x1 = a / b + (1.0 - a / b) * std::exp(-b * train_s);
  const double b_p = f / p.potentiation_time_s + 1.0 / p.potentiation_decay_s;
  const double p_inf = p.potentiation_max * f / p.potentiation_time_s / b_p;
  const double p1 = p_inf * (1.0 - std::exp(-b_p * train_s));
  // The rest: x → 1 with T_rec, P → 0 with T_pd.
  const double x2 = 1.0 - (1.0 - x1) * std::exp(-rest_s / p.recovery_time_s);
  const double p2 = p1 * std::exp(-rest_s / p.potentiation_decay_s);

  const StimulationRecord train{5.0, SteadyTrain(330, 50.0), 33.0};
  // A trial at the start itself and a later one do not count; order of the
  // records does not matter.
  const StimulationRecord later{45.0, SteadyTrain(100, 80.0), 33.0};
  const StrengthState s = StrengthAtStart(m, LinearIrc(), {later, train}, 45.0);
  EXPECT_NEAR(s.fitness, x2, 1e-13);
  EXPECT_NEAR(s.potentiation, p2, 1e-13);
  EXPECT_LT(x2, 0.93);  // the check is not trivial: the leg is still tired
  EXPECT_GT(p2, 0.05);

  // The same train as a trace: at its end the train's solution.
  const StrengthTrace trace(m, LinearIrc(), train.pulses, 33.0);
  EXPECT_NEAR(trace.end_s(), train_s, 1e-12);
  EXPECT_NEAR(trace.At(train_s).fitness, x1, 1e-13);
  EXPECT_NEAR(trace.At(train_s).potentiation, p1, 1e-13);
  // Before the first record the leg is rested.
  EXPECT_EQ(StrengthAtStart(m, LinearIrc(), {train}, 5.0).fitness, 1.0);
}

TEST(StrengthHistoryTest, OverlappingRecordsCountNoPulseTwice) {
  const StrengthModel m(StrengthParameters::RienerPrior());
  const StimulationRecord a{0.0, SteadyTrain(330, 50.0), 33.0};
  // A copy of the second half of `a`, recorded as starting 5 s in.
  PulseTrain half;
  for (int k = 165; k < 330; ++k) half.push_back({k / 33.0 - 5.0, 50.0});
  const StimulationRecord b{5.0, half, 33.0};
  const StrengthState one = StrengthAtStart(m, LinearIrc(), {a}, 40.0);
  const StrengthState both = StrengthAtStart(m, LinearIrc(), {a, b}, 40.0);
  EXPECT_NEAR(both.fitness, one.fitness, 1e-13);
}

TEST(StrengthHistoryTest, SimulationScalesTheActiveTorqueByTheStrength) {
  // Time constants too long to move over the trial: s ≡ s₀, so the strength
  // at fitness 0.6 is τ_scale × 0.6, in free swing (the arranged RK4 path)
  // and isometrically; relative to a reference of 0.6 it is the set itself.
  const ParameterSet set = ExampleParameterSet();
  ParameterSet weaker = set;
  weaker.active.torque_scale_nm *= 0.6;
  StrengthParameters frozen;
  frozen.fatigue_time_s = frozen.recovery_time_s = 1e15;
  SimulationStrength strength{frozen, {0.6, 0.0}, 1.0};
  PulseTrain pulses;
  for (int k = 0; k < 40; ++k) pulses.push_back({0.3 + k / 33.0, 45.0});
  SimulationOptions o;
  o.duration_s = 2.5;
  o.initial_angle_deg = 80.0;
  const SimulationResult base = SimulateFreeSwing(set, pulses, o);
  const SimulationResult ref = SimulateFreeSwing(weaker, pulses, o);
  EXPECT_TRUE(base.strength.empty());
  SimulationOptions with = o;
  with.strength = strength;
  const SimulationResult r = SimulateFreeSwing(set, pulses, with);
  ASSERT_EQ(r.strength.size(), r.size());
  double moved = 0.0;
  for (std::size_t i = 0; i < r.size(); ++i) {
    EXPECT_NEAR(r.angle_deg[i], ref.angle_deg[i], 1e-9);
    EXPECT_NEAR(r.strength[i], 0.6, 1e-12);
    EXPECT_EQ(r.activation[i], base.activation[i]);  // f_stim before the strength
    moved = std::max(moved, std::abs(r.angle_deg[i] - base.angle_deg[i]));
  }
  EXPECT_GT(moved, 1.0);
  with.strength->reference_factor = 0.6;
  const SimulationResult same = SimulateFreeSwing(set, pulses, with);
  for (std::size_t i = 0; i < r.size(); ++i) EXPECT_NEAR(same.angle_deg[i], base.angle_deg[i], 1e-9);

  with.strength->reference_factor = 1.0;
  const SimulationResult iso = SimulateIsometric(set, pulses, 70.0, with);
  const SimulationResult iso_ref = SimulateIsometric(weaker, pulses, 70.0, o);
  for (std::size_t i = 0; i < iso.size(); ++i) {
    EXPECT_NEAR(iso.torque_nm[i], iso_ref.torque_nm[i], 1e-12);
  }
  with.strength->reference_factor = 0.0;
  EXPECT_THROW(SimulateFreeSwing(set, pulses, with), std::invalid_argument);
}

}  // namespace
}  // namespace fesbench::model
