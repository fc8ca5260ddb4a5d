#include "model/tracking.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <stdexcept>

#include "model/contraction.h"
#include "model/joint_model.h"
#include "model/units.h"

namespace fesbench::model {
namespace {

// The model itself as the plant: Eq. 3.16 with the Hammerstein chain driven
// by the 33 Hz pulse clock, integrated at 1 kHz (RK4 on θ, θ̇ with the
// activation of the step's start). `strength` multiplies τ_scale: the leg
// is weaker (fatigue) or stronger than the set says.
class ModelPlant {
 public:
  ModelPlant(const ParameterSet& params, double strength, double angle_deg)
      : params_(params), joint_(JointModel::FromParameters(params)), chain_(params.contraction),
        strength_(strength), angle_(angle_deg) {}

  // Holds `amplitude_ma` for dt_s.
  void Advance(double amplitude_ma, double dt_s) {
    const double weight = PulseWeight(params_.irc, amplitude_ma, kDefaultPulseRateHz);
    const double end = t_ + dt_s;
    while (t_ < end - 1e-12) {
      const double h = std::min(1e-3, end - t_);
      const double pulse_t = static_cast<double>(next_pulse_) / kDefaultPulseRateHz;
      if (pulse_t < t_ + h - 1e-12) {
        Integrate(std::max(0.0, pulse_t - t_));
        x_[0] += params_.contraction.pole_per_s * weight;
        ++next_pulse_;
        continue;
      }
      Integrate(h);
    }
  }
  double angle_deg() const { return angle_; }

 private:
  void Integrate(double h) {
    if (h <= 0.0) return;
    const double f = chain_.Output(x_) * strength_;
    auto acc = [&](double th, double w) { return joint_.AccelerationDegS2(th, w, f); };
    const double k1v = acc(angle_, velocity_), k1x = velocity_;
    const double k2v = acc(angle_ + 0.5 * h * k1x, velocity_ + 0.5 * h * k1v),
                 k2x = velocity_ + 0.5 * h * k1v;
    const double k3v = acc(angle_ + 0.5 * h * k2x, velocity_ + 0.5 * h * k2v),
                 k3x = velocity_ + 0.5 * h * k2v;
    const double k4v = acc(angle_ + h * k3x, velocity_ + h * k3v), k4x = velocity_ + h * k3v;
    angle_ += h / 6.0 * (k1x + 2 * k2x + 2 * k3x + k4x);
    velocity_ += h / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v);
    x_ = chain_.Propagate(x_, h);
    t_ += h;
  }

  ParameterSet params_;
  JointModel joint_;
  ContractionPropagator chain_;
  ContractionState x_{};
  double strength_;
  double angle_;
  double velocity_ = 0.0;
  double t_ = 0.0;
  std::int64_t next_pulse_ = 0;
};

struct Tracked {
  double rms_deg = 0.0;
  double max_amplitude_ma = 0.0;
  double final_tau_scale_nm = 0.0;
};

// Closed loop at 200 Hz; RMS from `judge_from_s` on.
Tracked Track(const ParameterSet& params, const KneeTarget& target, TrackingOptions options,
              double strength, double judge_from_s = 2.0) {
  TrackingController controller(params, target, options);
  ModelPlant plant(params, strength, target.angle_deg.front());
  Tracked out;
  double sum = 0.0;
  std::size_t count = 0;
  for (std::size_t i = 0; i < target.size(); ++i) {
    const TrackingSample s = controller.Update(plant.angle_deg());
    out.max_amplitude_ma = std::max(out.max_amplitude_ma, s.amplitude_ma);
    if (static_cast<double>(i) / target.rate_hz >= judge_from_s) {
      sum += s.error_deg * s.error_deg;
      ++count;
    }
    plant.Advance(s.amplitude_ma, 1.0 / target.rate_hz);
  }
  out.rms_deg = std::sqrt(sum / static_cast<double>(count));
  out.final_tau_scale_nm = controller.tau_scale_nm();
  return out;
}

TrackingOptions Options(ControllerKind kind) {
  TrackingOptions o;
  o.kind = kind;
  o.threshold_ma = 20.0;
  o.max_amplitude_ma = 60.0;
  return o;
}

TEST(ControllerKindTest, NamesRoundTrip) {
  for (ControllerKind k :
       {ControllerKind::kPid, ControllerKind::kInverseModel, ControllerKind::kAdaptive}) {
    EXPECT_EQ(ControllerKindOf(ControllerKindName(k)), k);
  }
  EXPECT_FALSE(ControllerKindOf("bang_bang"));
}

TEST(TuneGainsTest, TheLoopGainIsAHalfForPidAndAQuarterAroundTheFeedforward) {
  const ParameterSet params = ExampleParameterSet();
  const KneeTarget target = HoldsTarget({55.0}, 2.0, 1.0);
  const Pid::Gains pid = TuneGains(params, target, Options(ControllerKind::kPid));
  const Pid::Gains ff = TuneGains(params, target, Options(ControllerKind::kInverseModel));
  EXPECT_NEAR(pid.kp_ma_per_deg, 2.0 * ff.kp_ma_per_deg, 1e-12);
  EXPECT_NEAR(pid.ki_ma_per_deg_s, pid.kp_ma_per_deg / 1.0, 1e-12);
  EXPECT_NEAR(pid.kd_ma_s_per_deg, pid.kp_ma_per_deg * 0.1, 1e-12);
  // Closed form of the static loop gain: hold at 55° with the activation f_m,
  // then the equilibrium moves by g = K_u/K_θ deg per mA (small signal).
  const JointModel joint = JointModel::FromParameters(params);
  const double gain = joint.ActiveGain(55.0, 0.0);
  const double f_m = -joint.PassiveAngleTorque(55.0) / gain;
  const auto total = [&](double th) {
    return joint.PassiveAngleTorque(th) + f_m * joint.ActiveGain(th, 0.0);
  };
  const double k_theta = std::abs(total(56.0) - total(54.0)) / 2.0;
  const double slope = (params.irc(60.0) - params.irc(20.0)) / 40.0;
  EXPECT_NEAR(pid.kp_ma_per_deg * gain * slope / k_theta, 0.5, 1e-9);
}

TEST(TrackingControllerTest, TheInverseModelTracksItsOwnLegAndBeatsPid) {
  const ParameterSet params = ExampleParameterSet();
  const KneeTarget sine = SineTarget(30.0, 80.0, 0.2, 30.0);
  const Tracked inverse = Track(params, sine, Options(ControllerKind::kInverseModel), 1.0);
  const Tracked pid = Track(params, sine, Options(ControllerKind::kPid), 1.0);
  const Tracked adaptive = Track(params, sine, Options(ControllerKind::kAdaptive), 1.0);
  std::cout << "[ figure ] 0.2 Hz sine 30–80° on the example leg (the model as plant): RMS "
            << "inverse_model " << inverse.rms_deg << "°, adaptive " << adaptive.rms_deg
            << "°, pid " << pid.rms_deg << "°; τ̂_scale " << adaptive.final_tau_scale_nm
            << " N·m (set " << params.active.torque_scale_nm << ")\n";
  EXPECT_LT(inverse.rms_deg, 1.5);
  EXPECT_LT(inverse.rms_deg, 0.5 * pid.rms_deg);
  EXPECT_LT(adaptive.rms_deg, 1.5);
  // The plant is the model: the estimate stays near the set's τ_scale.
  EXPECT_NEAR(adaptive.final_tau_scale_nm, params.active.torque_scale_nm,
              0.1 * params.active.torque_scale_nm);
  for (const Tracked& t : {inverse, pid, adaptive}) EXPECT_LE(t.max_amplitude_ma, 60.0);
}

TEST(TrackingControllerTest, AdaptiveFollowsAWeakerLeg) {
  // The leg gives 60 % of the set's τ_scale (fatigue): the adaptive
  // controller's τ̂ finds it and tracks better than the fixed inverse.
  const ParameterSet params = ExampleParameterSet();
  const KneeTarget sine = SineTarget(30.0, 80.0, 0.2, 40.0);
  const Tracked inverse = Track(params, sine, Options(ControllerKind::kInverseModel), 0.6, 10.0);
  const Tracked adaptive = Track(params, sine, Options(ControllerKind::kAdaptive), 0.6, 10.0);
  std::cout << "[ figure ] leg at 60 % strength: RMS inverse_model " << inverse.rms_deg
            << "°, adaptive " << adaptive.rms_deg << "°; τ̂_scale "
            << adaptive.final_tau_scale_nm << " N·m (true "
            << 0.6 * params.active.torque_scale_nm << ")\n";
  EXPECT_NEAR(adaptive.final_tau_scale_nm, 0.6 * params.active.torque_scale_nm,
              0.1 * params.active.torque_scale_nm);
  EXPECT_LT(adaptive.rms_deg, inverse.rms_deg);
}

TEST(TrackingControllerTest, HoldsSettleAndTheOutputStaysWithinItsBounds) {
  const ParameterSet params = ExampleParameterSet();
  const KneeTarget holds = HoldsTarget({70.0, 40.0, 60.0}, 8.0, 1.0);
  for (ControllerKind k :
       {ControllerKind::kPid, ControllerKind::kInverseModel, ControllerKind::kAdaptive}) {
    TrackingController c(params, holds, Options(k));
    ModelPlant plant(params, 1.0, 70.0);
    double last_error = 0.0;
    for (std::size_t i = 0; i < holds.size(); ++i) {
      const TrackingSample s = c.Update(plant.angle_deg());
      ASSERT_GE(s.amplitude_ma, 0.0);
      ASSERT_LE(s.amplitude_ma, 60.0);
      EXPECT_NEAR(s.correction_ma, s.amplitude_ma - s.feedforward_ma, 1e-12);
      last_error = s.error_deg;
      plant.Advance(s.amplitude_ma, 1.0 / holds.rate_hz);
    }
    EXPECT_LT(std::abs(last_error), 1.0) << ControllerKindName(k) << ": settled at the last hold";
  }
}

TEST(TrackingControllerTest, RefusesImpossibleOptions) {
  const ParameterSet params = ExampleParameterSet();
  const KneeTarget holds = HoldsTarget({50.0}, 1.0, 1.0);
  TrackingOptions bad = Options(ControllerKind::kInverseModel);
  bad.max_amplitude_ma = 10.0;  // below the threshold
  EXPECT_THROW(TrackingController(params, holds, bad), std::invalid_argument);
  bad = Options(ControllerKind::kAdaptive);
  bad.forgetting = 1.5;
  EXPECT_THROW(TrackingController(params, holds, bad), std::invalid_argument);
  bad = Options(ControllerKind::kPid);
  bad.velocity_filter_hz = 90.0;  // ω·dt > 1 at 200 Hz
  EXPECT_THROW(TrackingController(params, holds, bad), std::invalid_argument);
  TrackingController ok(params, holds, Options(ControllerKind::kPid));
  EXPECT_THROW(ok.Update(std::nan("")), std::invalid_argument);
}

}  // namespace
}  // namespace fesbench::model
