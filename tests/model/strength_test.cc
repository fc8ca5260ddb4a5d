// The strength state (docs/MODEL.md, "Strength that changes with use"):
// its closed-form propagation against the solution of the fitness and
// potentiation equations written out here, against Boost.Odeint's
// Dormand–Prince integration of the same equations, and as a pulse train
// runs and stops.
#include "model/strength.h"

#include <gtest/gtest.h>

#include <array>
#include <boost/numeric/odeint.hpp>
#include <cmath>
#include <stdexcept>

namespace fesbench::model {
namespace {

// The equations of model/strength.h integrated by an adaptive Dormand–Prince
// 5(4) stepper to a tolerance far below the tests' (independent of the
// closed form).
StrengthState Integrate(const StrengthParameters& p, StrengthState s, double f, double t_s) {
  using State = std::array<double, 2>;
  State y{s.fitness, s.potentiation};
  const auto rhs = [&](const State& x, State& dxdt, double /*t*/) {
    dxdt[0] = (p.min_fitness - x[0]) * f / p.fatigue_time_s +
              (1.0 - x[0]) * (1.0 - p.recovery_gating * f) / p.recovery_time_s;
    dxdt[1] = (p.potentiation_max - x[1]) * f / p.potentiation_time_s -
              x[1] / p.potentiation_decay_s;
  };
  namespace odeint = boost::numeric::odeint;
  odeint::integrate_adaptive(
      odeint::make_controlled(1e-12, 1e-12, odeint::runge_kutta_dopri5<State>()), rhs, y, 0.0,
      t_s, 0.01);
  return {y[0], y[1]};
}

TEST(StrengthTest, DecayUnderAConstantTrainIsTheClosedForm) {
  // Riener's prior at full activation: dx/dt = (x_min − x)/T_fat, so
  // x(t) = x_min + (1 − x_min)·e^(−t/T_fat) from rest.
  const StrengthParameters p = StrengthParameters::RienerPrior();
  const StrengthModel m(p);
  for (double t : {0.0, 0.005, 1.0, 10.0, 30.0, 120.0}) {
    const StrengthState s = m.Propagate({}, 1.0, t);
    const double expected = p.min_fitness + (1.0 - p.min_fitness) * std::exp(-t / p.fatigue_time_s);
    EXPECT_NEAR(s.fitness, expected, 1e-14) << "t = " << t;
    EXPECT_NEAR(StrengthFactor(s), expected, 1e-14);  // no potentiation in the prior
  }
  // Part activation f = 0.4: a = x_min·f/T_fat + (1 − f)/T_rec, b = f/T_fat +
  // (1 − f)/T_rec, x(t) = a/b + (1 − a/b)·e^(−b·t).
  const double f = 0.4;
  const double a = p.min_fitness * f / p.fatigue_time_s + (1.0 - f) / p.recovery_time_s;
  const double b = f / p.fatigue_time_s + (1.0 - f) / p.recovery_time_s;
  for (double t : {0.5, 20.0, 200.0}) {
    EXPECT_NEAR(m.Propagate({}, f, t).fitness, a / b + (1.0 - a / b) * std::exp(-b * t), 1e-14);
  }
  EXPECT_NEAR(m.Steady(f).fitness, a / b, 1e-15);
  EXPECT_NEAR(m.FitnessTimeConstant(f), 1.0 / b, 1e-12);
}

TEST(StrengthTest, RecoveryAfterTheTrainStopsIsTheClosedForm) {
  // 60 s of a train at f = 0.8, then rest: x(t) = 1 − (1 − x₀)·e^(−t/T_rec).
  const StrengthModel m(StrengthParameters::RienerPrior());
  const StrengthState tired = m.Propagate({}, 0.8, 60.0);
  ASSERT_LT(tired.fitness, 0.4);  // 0.305
  const double t_rec = m.parameters().recovery_time_s;
  for (double t : {0.1, 10.0, 50.0, 300.0}) {
    EXPECT_NEAR(m.Propagate(tired, 0.0, t).fitness,
                1.0 - (1.0 - tired.fitness) * std::exp(-t / t_rec), 1e-14)
        << "t = " << t;
  }
  EXPECT_DOUBLE_EQ(m.Steady(0.0).fitness, 1.0);
}

TEST(StrengthTest, FirstOrderFormWithPotentiationMatchesItsEquations) {
  // dF/dt = r·f·(1 − F) − F/T, dP/dt = r_p·f·(P_max − P) − P/T_pd: the
  // simulated leg's form (docs/MODEL.md), fatigue rate five times 0.02 s⁻¹.
  const StrengthParameters p = StrengthParameters::FirstOrder(0.1, 30.0, 0.3, 0.5, 60.0);
  const StrengthModel m(p);
  const double f = 0.6;
  const double k = 0.1 * f + 1.0 / 30.0;  // the fatigue's rate constant
  const double f_inf = 0.1 * f / k;
  const double kp = 0.5 * f + 1.0 / 60.0;
  const double p_inf = 0.3 * 0.5 * f / kp;
  for (double t : {1.0, 15.0, 90.0}) {
    const StrengthState s = m.Propagate({}, f, t);
    EXPECT_NEAR(1.0 - s.fitness, f_inf * (1.0 - std::exp(-k * t)), 1e-14) << "t = " << t;
    EXPECT_NEAR(s.potentiation, p_inf * (1.0 - std::exp(-kp * t)), 1e-14) << "t = " << t;
    EXPECT_NEAR(StrengthFactor(s), s.fitness * (1.0 + s.potentiation), 1e-15);
  }
  // After the train, F and P decay with their own time constants.
  const StrengthState end = m.Propagate({}, f, 90.0);
  const StrengthState rest = m.Propagate(end, 0.0, 20.0);
  EXPECT_NEAR(1.0 - rest.fitness, (1.0 - end.fitness) * std::exp(-20.0 / 30.0), 1e-14);
  EXPECT_NEAR(rest.potentiation, end.potentiation * std::exp(-20.0 / 60.0), 1e-14);
}

TEST(StrengthTest, ClosedFormAgreesWithNumericalIntegration) {
  StrengthParameters p = StrengthParameters::RienerPrior();
  p.recovery_gating = 0.5;
  p.potentiation_max = 0.2;
  const StrengthModel m(p);
  const StrengthState start{0.7, 0.05};
  for (double f : {0.0, 0.25, 1.0}) {
    for (double t : {0.3, 7.0, 45.0}) {
      const StrengthState exact = m.Propagate(start, f, t);
      const StrengthState numeric = Integrate(p, start, f, t);
      EXPECT_NEAR(exact.fitness, numeric.fitness, 1e-9) << "f = " << f << ", t = " << t;
      EXPECT_NEAR(exact.potentiation, numeric.potentiation, 1e-9) << "f = " << f << ", t = " << t;
    }
  }
}

TEST(StrengthTest, StepsComposeExactly) {
  // A 5 ms control sample at a time gives the interval's single step: the
  // propagation is exact, not an integration that accumulates error.
  const StrengthModel m(StrengthParameters::FirstOrder(0.1, 30.0, 0.3));
  StrengthState stepped;
  for (int i = 0; i < 24000; ++i) stepped = m.Propagate(stepped, 0.5, 0.005);  // 120 s
  const StrengthState once = m.Propagate({}, 0.5, 120.0);
  EXPECT_NEAR(stepped.fitness, once.fitness, 1e-12);
  EXPECT_NEAR(stepped.potentiation, once.potentiation, 1e-12);
}

TEST(StrengthTest, RejectsBadParametersAndInputs) {
  StrengthParameters p;
  p.fatigue_time_s = 0.0;
  EXPECT_THROW(StrengthModel{p}, std::invalid_argument);
  p = {};
  p.min_fitness = 1.0;
  EXPECT_THROW(StrengthModel{p}, std::invalid_argument);
  p = {};
  p.recovery_gating = 1.5;
  EXPECT_THROW(StrengthModel{p}, std::invalid_argument);
  const StrengthModel m(StrengthParameters{});
  EXPECT_THROW(m.Propagate({}, NAN, 1.0), std::invalid_argument);
  EXPECT_THROW(m.Propagate({}, 0.5, -1.0), std::invalid_argument);
  // Activation outside [0, 1] is clamped.
  EXPECT_DOUBLE_EQ(m.Propagate({}, 2.0, 10.0).fitness, m.Propagate({}, 1.0, 10.0).fitness);
}

}  // namespace
}  // namespace fesbench::model
