#include "model/contraction.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <unsupported/Eigen/MatrixFunctions>
#include <vector>

#include "model/parameter_set.h"

namespace fesbench::model {
namespace {

// Time of the maximum of h_n on a fine grid.
double NumericPeak(const ContractionParams& c) {
  double best_t = 0.0, best = -1.0;
  for (double t = 0.0; t < 1.0; t += 1e-5) {
    const double v = ImpulseResponse(c, t);
    if (v > best) best = v, best_t = t;
  }
  return best_t;
}

TEST(ContractionTest, ImpulseResponsePeaksAtNMinusOneOverA) {
  for (int n : {2, 3}) {
    for (double a : {11.7, 25.0}) {
      const ContractionParams c{n, a};
      EXPECT_NEAR(NumericPeak(c), (n - 1) / a, 2e-5) << "n=" << n << " a=" << a;  // Eqs. 4.2, 4.4
      EXPECT_DOUBLE_EQ(ImpulseResponsePeakTime(c), (n - 1) / a);
    }
  }
}

TEST(ContractionTest, ImpulseResponseHasUnitArea) {
  for (int n : {2, 3}) {
    const ContractionParams c{n, 20.0};
    double area = 0.0;
    const double dt = 1e-5;
    for (double t = 0.0; t < 3.0; t += dt)
      area += 0.5 * dt * (ImpulseResponse(c, t) + ImpulseResponse(c, t + dt));
    EXPECT_NEAR(area, 1.0, 1e-8);
    EXPECT_EQ(ImpulseResponse(c, -0.1), 0.0);
  }
}

TEST(ContractionTest, StateSpaceHasUnitDcGain) {
  for (int n : {2, 3}) {
    const ContractionStateSpace ss = MakeContractionStateSpace({n, 25.0});
    ASSERT_EQ(ss.a.rows(), n);
    const double dc = -(ss.c * ss.a.inverse() * ss.b)(0, 0);  // H(0) = −C·A⁻¹·B
    EXPECT_NEAR(dc, 1.0, 1e-12);
  }
}

TEST(ContractionTest, PropagatorMatchesMatrixExponential) {
  for (int n : {2, 3}) {
    const ContractionParams c{n, 25.0};
    const ContractionStateSpace ss = MakeContractionStateSpace(c);
    ContractionPropagator prop(c);
    const ContractionState x0{0.7, -0.2, 0.4};
    for (double dt : {0.0, 0.001, 0.0123, 0.3}) {
      Eigen::VectorXd v(n);
      for (int i = 0; i < n; ++i) v(i) = x0[i];
      const Eigen::VectorXd expected = (ss.a * dt).exp() * v;
      const ContractionState got = prop.Propagate(x0, dt);
      for (int i = 0; i < n; ++i) EXPECT_NEAR(got[i], expected(i), 1e-14) << "dt=" << dt;
      EXPECT_NEAR(prop.OutputAfter(x0, dt), expected(n - 1), 1e-14);
      // A split interval's steps from one exp: h/2 and h both.
      const ContractionPropagator::HalfAndFull both = prop.StepsFor(dt);
      const Eigen::VectorXd half = (ss.a * (0.5 * dt)).exp() * v;
      const ContractionState got_full = prop.Propagate(x0, both.full);
      const ContractionState got_half = prop.Propagate(x0, both.half);
      for (int i = 0; i < n; ++i) {
        EXPECT_NEAR(got_full[i], expected(i), 1e-14) << "dt=" << dt;
        EXPECT_NEAR(got_half[i], half(i), 1e-14) << "dt=" << dt;
      }
      EXPECT_NEAR(prop.OutputAfter(x0, both.half), half(n - 1), 1e-14);
    }
  }
}

TEST(ContractionTest, ChainImpulseEqualsClosedForm) {
  for (int n : {2, 3}) {
    const ContractionParams c{n, 18.0};
    ContractionPropagator prop(c);
    ContractionState x{};
    prop.ApplyImpulse(x, 1.0);
    for (double t : {0.01, 0.05, 0.111, 0.4}) {
      EXPECT_NEAR(prop.OutputAfter(x, t), ImpulseResponse(c, t), 1e-12);
    }
  }
}

TEST(ContractionTest, SinglePulseGivesScaledTwitch) {
  const ParameterSet p = ExampleParameterSet();  // R(40 mA) = 0.85
  const PulseTrain pulses = {{0.1003, 40.0}};
  std::vector<double> t;
  for (int i = 0; i < 200; ++i) t.push_back(i * 0.0025);
  const auto f = ActivationAt(p.contraction, p.irc, pulses, 33.0, t);
  for (std::size_t i = 0; i < t.size(); ++i) {
    EXPECT_NEAR(f[i], ImpulseResponse(p.contraction, t[i] - 0.1003) * 0.85 / 33.0, 1e-12);
  }
}

TEST(ContractionTest, SteadyTrainSettlesAtRecruitment) {
  const ParameterSet p = ExampleParameterSet();
  for (int n : {2, 3}) {
    const ContractionParams c{n, 25.0};
    for (double u : {25.0, 35.0, 45.0}) {
      const double rate = 33.0;
      PulseTrain pulses;
      for (int k = 0; k < 100; ++k) pulses.push_back({k / rate, u});
      // Average over the last complete pulse period, 1000 samples.
      const double t0 = 98.0 / rate;
      std::vector<double> t;
      for (int i = 0; i < 1000; ++i) t.push_back(t0 + (i + 0.5) / (1000.0 * rate));
      const auto f = ActivationAt(c, p.irc, pulses, rate, t);
      double mean = 0.0;
      for (double v : f) mean += v / 1000.0;
      const double r = p.irc(u);
      EXPECT_NEAR(mean, r, 0.01 * r) << "n=" << n << " u=" << u;
    }
  }
}

TEST(ContractionTest, RejectsBadInput) {
  const ParameterSet p = ExampleParameterSet();
  const std::vector<double> t = {0.0, 0.1};
  EXPECT_THROW(ValidateContraction({4, 25.0}), std::invalid_argument);
  EXPECT_THROW(ValidateContraction({3, 0.0}), std::invalid_argument);
  EXPECT_THROW(ValidateContraction({3, NAN}), std::invalid_argument);
  EXPECT_THROW(ActivationAt(p.contraction, p.irc, {{0.2, 30}, {0.1, 30}}, 33.0, t),
               std::invalid_argument);
  EXPECT_THROW(ActivationAt(p.contraction, p.irc, {{0.2, 30}, {0.2, 30}}, 33.0, t),
               std::invalid_argument);
  EXPECT_THROW(ActivationAt(p.contraction, p.irc, {{NAN, 30}}, 33.0, t), std::invalid_argument);
  EXPECT_THROW(ActivationAt(p.contraction, p.irc, {{0.1, -1}}, 33.0, t), std::invalid_argument);
  EXPECT_THROW(ActivationAt(p.contraction, p.irc, {}, 0.0, t), std::invalid_argument);
  const std::vector<double> decreasing = {0.2, 0.1};
  EXPECT_THROW(ActivationAt(p.contraction, p.irc, {}, 33.0, decreasing), std::invalid_argument);
}

}  // namespace
}  // namespace fesbench::model
