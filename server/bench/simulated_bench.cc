#include "server/bench/simulated_bench.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "api/virtual_subject.h"
#include "model/integrators.h"
#include "model/units.h"

namespace fesbench::server {
namespace {

using model::DegToRad;
using model::kStandardGravity_m_s2;
using model::RadToDeg;

// Sensors (§5.1): 12-bit A/D, −2048…2047.
constexpr double kTorqueLsbNm = 0.0381;
constexpr double kAdcMinCode = -2048.0, kAdcMaxCode = 2047.0;
constexpr double kPotTurnDeg = 120.0;               // one potentiometer turn of knee rotation.
constexpr double kAngleLsbDeg = kPotTurnDeg / 4096.0;
// The potentiometer's turn spans 0–120° of flexion: mid-scale (code 0) is 60°.
constexpr double kAngleMidScaleDeg = kPotTurnDeg / 2.0;
constexpr double kAccelLsbM_s2 = 20.0 * kStandardGravity_m_s2 / 4096.0;  // ±10 g.

// Motor (§5.1): PD servo at the knee, gearbox drag when unpowered.
constexpr double kServoKpNmPerDeg = 35.0;    // ≈ 2000 N·m/rad.
constexpr double kServoKdNmPerDegS = 0.75;   // ≈ 43 N·m·s/rad.
constexpr double kDragNmPerDegS = 0.02;
constexpr double kDragCoulombNm = 1.0;
constexpr double kDragVelocityDegS = 1.0;
constexpr double kLimitSwitchMarginDeg = 2.0;
// The lock engages once the servo has brought the brace near its set-point
// and nearly still; gravity leaves the servo a droop of ~0.1–0.2°.
constexpr double kLockToleranceDeg = 0.5;
constexpr double kLockVelocityDegS = 5.0;

// Hard stops: stiff one-sided spring–damper.
constexpr double kStopStiffnessNmPerDeg = 10000.0;
constexpr double kStopDampingNmPerDegS = 20.0;
constexpr double kStopZoneDeg = 5.0;        // finer sub-steps this close to a stop
constexpr double kStopZoneSubStepS = 1e-4;

// EMG: M-wave shape after each pulse.
constexpr double kMWavePeriodS = 0.012;
constexpr double kMWaveDecayS = 0.006;
constexpr double kMWaveSpanS = 0.04;
constexpr std::size_t kMaxEmgSamples = 600'000;  // 10 min at 1 kHz.
constexpr std::size_t kMaxPulses = 1'000'000;     // ~8 h at 33 Hz.

enum NoiseChannel { kNoiseAngle = 1, kNoiseTorque, kNoiseAccel, kNoiseEmg, kNoiseBurstEmg };

std::uint64_t SplitMix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

double UnitUniform(std::uint64_t bits) { return static_cast<double>(bits >> 11) * 0x1.0p-53; }

// The 12-bit A/D reading of value, for a channel whose code 0 is mid_scale.
double Quantise(double value, double lsb, double mid_scale = 0.0) {
  const double code = std::clamp(std::round((value - mid_scale) / lsb), kAdcMinCode, kAdcMaxCode);
  return mid_scale + code * lsb;
}

model::ContractionParams AlternateContraction(const model::ContractionParams& c) {
  // The other order with the same twitch peak (n − 1)/a (Eqs. 4.2, 4.4).
  const int n_alt = c.order == 3 ? 2 : 3;
  return {n_alt, c.pole_per_s * (n_alt - 1) / (c.order - 1)};
}

double RestAngle(const model::JointModel& jm) {
  const double ptv0 = jm.PassiveVelocityTorque(0.0);
  const auto g = [&](double th) { return jm.PassiveAngleTorque(th) + ptv0; };
  for (double th = 10.0; th < 110.0 - 1e-9; th += 0.5) {
    if (g(th) <= 0.0 && g(th + 0.5) > 0.0) {
      double lo = th, hi = th + 0.5;
      for (int i = 0; i < 60; ++i) {
        const double mid = 0.5 * (lo + hi);
        (g(mid) <= 0.0 ? lo : hi) = mid;
      }
      return 0.5 * (lo + hi);
    }
  }
  return 90.0;
}

}  // namespace

struct SimulatedBench::Forces {
  double pta = 0, ptv = 0, hyst_rate = 0, fric = 0, muscle = 0, vol = 0, motor = 0, stop = 0;
  double accel_deg_s2 = 0;
};

SimulatedBench::SimulatedBench(VirtualSubject subject, SimulatedBenchOptions options)
    : subject_(std::move(subject)),
      options_(std::move(options)),
      joint_(model::JointModel::FromParameters(subject_.truth)),
      pacer_(options_.clock, options_.time_scale),
      pulse_clock_(options_.limits.pulse_rate_hz),
      primary_(subject_.truth.contraction),
      alternate_(AlternateContraction(subject_.truth.contraction)),
      burst_rng_(SplitMix64(subject_.seed ^ SplitMix64(options_.seed ^ 0xB0B5ULL))) {
  noise_seed_ = SplitMix64(subject_.seed ^ SplitMix64(options_.seed));
  hang_deg_ = HangingAngleDeg(subject_.anthropometrics);
  const double th0 = options_.initial_angle_deg.value_or(RestAngle(joint_));
  x_ << std::clamp(th0, options_.limits.min_angle_deg, options_.limits.max_angle_deg), 0.0, 0.0;
  ce_angle_deg_ = x_[0];
  mode_ = options_.initial_mode;
  setpoint_deg_ = options_.initial_setpoint_deg.value_or(x_[0]);
  ScheduleBursts();
  ControlStepStart();
}

SimulatedBench::~SimulatedBench() = default;

api::Result<std::unique_ptr<SimulatedBench>> SimulatedBench::Create(VirtualSubject subject,
                                                                    SimulatedBenchOptions options) {
  if (api::Status st = ValidateVirtualSubject(subject); !st.ok()) return st;
  return std::unique_ptr<SimulatedBench>(
      new SimulatedBench(std::move(subject), std::move(options)));
}

void SimulatedBench::set_time_scale(double time_scale) {
  std::lock_guard lock(mu_);
  pacer_.set_time_scale(time_scale);
}

// --- stimulator -------------------------------------------------------------

void SimulatedBench::SetStimAmplitude(double stim_ma) {
  std::lock_guard lock(mu_);
  commanded_ma_ = (std::isfinite(stim_ma) && stim_ma > 0.0)
                      ? std::min(stim_ma, options_.limits.max_stim_ma)
                      : 0.0;
}

void SimulatedBench::TriggerPulse(double stim_ma) {
  std::lock_guard lock(mu_);
  if (HardwareEStopped() || !std::isfinite(stim_ma) || !(stim_ma > 0.0)) return;
  FirePulse(std::min(stim_ma, options_.limits.max_stim_ma));
}

void SimulatedBench::RestartPulseClock() {
  std::lock_guard lock(mu_);
  pulse_clock_ = model::PulseClock(options_.limits.pulse_rate_hz, t_);
  next_grid_k_ = 0;
}

void SimulatedBench::FireDuePulses() {
  // docs/MODEL.md, pulse timing: every grid time reached fires if the amplitude is > 0
  // (and the e-stop is not latched); the grid runs on either way.
  while (pulse_clock_.TimeOf(next_grid_k_) <= t_ + model::kPulseTimeToleranceS) {
    if (commanded_ma_ > 0.0 && !HardwareEStopped()) FirePulse(commanded_ma_);
    ++next_grid_k_;
  }
}

void SimulatedBench::FirePulse(double stim_ma) {
  // docs/MODEL.md: an impulse of weight R(u)/f_pulse into H_n. With twitch
  // variation (Fig. 3-8) a level-dependent share drives the alternate chain.
  const double r = std::max(0.0, subject_.truth.irc(stim_ma));
  const double weight = r / options_.limits.pulse_rate_hz;
  const double share = std::clamp(subject_.fidelity.twitch_variation * r, 0.0, 1.0);
  primary_.ApplyImpulse(chain1_, (1.0 - share) * weight);
  if (share > 0.0) alternate_.ApplyImpulse(chain2_, share * weight);
  last_pulse_t_s_ = t_;
  last_pulse_ma_ = stim_ma;
  last_pulse_r_ = r;
  for (auto* log : {&delivered_, &readback_}) {
    if (log->size() >= kMaxPulses) log->erase(log->begin(), log->begin() + kMaxPulses / 2);
    log->push_back({t_, stim_ma});
  }
}

double SimulatedBench::RawActivationAfter(double dt_s) {
  double f = dt_s == 0.0 ? primary_.Output(chain1_) : primary_.OutputAfter(chain1_, dt_s);
  if (subject_.fidelity.twitch_variation > 0.0) {
    f += dt_s == 0.0 ? alternate_.Output(chain2_) : alternate_.OutputAfter(chain2_, dt_s);
  }
  return f;
}

double SimulatedBench::Potentiated(double f_raw) const {
  // §3.3 potentiation: twitches (small f) gain 1 + P, fused tetanus (f = 1) none.
  const double p = potentiation_;
  return p == 0.0 ? f_raw : (1.0 + p) * f_raw / (1.0 + p * f_raw);
}

// --- motor ------------------------------------------------------------------

void SimulatedBench::SetMotorMode(MotorMode mode) {
  std::lock_guard lock(mu_);
  if (mode != mode_) lock_engaged_ = false;
  mode_ = mode;
  TryEngageLock();
}

void SimulatedBench::SetMotorSetpoint(double angle_deg) {
  std::lock_guard lock(mu_);
  if (!std::isfinite(angle_deg)) return;
  const double dt = t_ - setpoint_time_s_;
  if (dt > 1e-9) {
    setpoint_velocity_deg_s_ = dt <= 0.05 ? (angle_deg - setpoint_deg_) / dt : 0.0;
    setpoint_velocity_deg_s_ = std::clamp(setpoint_velocity_deg_s_, -1000.0, 1000.0);
    setpoint_time_s_ = t_;
  }
  if (angle_deg != setpoint_deg_) lock_engaged_ = false;
  setpoint_deg_ = angle_deg;
  TryEngageLock();
}

MotorMode SimulatedBench::EffectiveMode() const {
  return HardwareEStopped() ? MotorMode::kDisabled : mode_;
}

double SimulatedBench::MotorTorque(double angle_deg, double velocity_deg_s) const {
  switch (EffectiveMode()) {
    case MotorMode::kDecoupled:
      return 0.0;
    case MotorMode::kDisabled:
      return -(kDragNmPerDegS * velocity_deg_s +
               kDragCoulombNm * std::tanh(velocity_deg_s / kDragVelocityDegS));
    case MotorMode::kPosition:
    case MotorMode::kLocked: {
      const double lim = options_.limits.max_motor_torque_nm;
      double tau = kServoKpNmPerDeg * (setpoint_deg_ - angle_deg) +
                   kServoKdNmPerDegS * (setpoint_velocity_deg_s_ - velocity_deg_s);
      tau = std::clamp(tau, -lim, lim);
      // Limit switches keep the motor from forcing the limb into the stops (§5.1).
      if (angle_deg >= options_.limits.max_angle_deg - kLimitSwitchMarginDeg) tau = std::min(tau, 0.0);
      if (angle_deg <= options_.limits.min_angle_deg + kLimitSwitchMarginDeg) tau = std::max(tau, 0.0);
      return tau;
    }
  }
  return 0.0;
}

double SimulatedBench::StopTorque(double angle_deg, double velocity_deg_s) const {
  const double lo = options_.limits.min_angle_deg, hi = options_.limits.max_angle_deg;
  if (angle_deg < lo) {
    return std::max(0.0, kStopStiffnessNmPerDeg * (lo - angle_deg) -
                             kStopDampingNmPerDegS * velocity_deg_s);
  }
  if (angle_deg > hi) {
    return std::min(0.0, -kStopStiffnessNmPerDeg * (angle_deg - hi) -
                             kStopDampingNmPerDegS * velocity_deg_s);
  }
  return 0.0;
}

// --- voluntary bursts -----------------------------------------------------------

void SimulatedBench::ScheduleBursts() {
  const double rate = subject_.fidelity.cocontraction_per_min;
  if (rate <= 0.0) {
    burst_start_s_ = burst_end_s_ = 1e300;
    return;
  }
  const double base = std::isfinite(burst_end_s_) && burst_end_s_ < 1e299 ? burst_end_s_ : t_;
  const double u1 = UnitUniform(burst_rng_()), u2 = UnitUniform(burst_rng_());
  burst_start_s_ = base - std::log1p(-u1) * 60.0 / rate;
  burst_end_s_ = burst_start_s_ + 0.5 + u2;
}

double SimulatedBench::VoluntaryEnvelope(double t_s) const {
  if (t_s <= burst_start_s_ || t_s >= burst_end_s_) return 0.0;
  const double s = std::sin(model::kPi * (t_s - burst_start_s_) / (burst_end_s_ - burst_start_s_));
  return s * s;
}

// --- mechanics --------------------------------------------------------------

SimulatedBench::Forces SimulatedBench::CalcForces(double t_s, const State& x, double activation,
                                                  double ce_deg) const {
  const Fidelity& fid = subject_.fidelity;
  const double th = x[0], om = x[1], hyst = x[2];
  Forces f;
  f.pta = joint_.PassiveAngleTorque(th);
  f.ptv = joint_.PassiveVelocityTorque(om);
  if (fid.hysteresis_nm > 0.0) {
    // Dahl-type loop: dτ_h/dθ = (H·sgn θ̇ − τ_h)/θ_h (Fig. 3-7, §6.6).
    f.hyst_rate = (om * fid.hysteresis_nm - std::abs(om) * hyst) / fid.hysteresis_angle_deg;
  }
  if (fid.static_friction_nm > 0.0) {
    f.fric = fid.static_friction_nm * std::tanh(om / fid.friction_velocity_deg_s);  // Fig. 6-22
  }
  const double force_gain = 1.0 - fatigue_;
  if (fid.series_stiffness_nm_per_deg > 0.0) {
    // Eq. 3.5: the SE carries the CE torque; it cannot push (slack, Eq. 3.8).
    f.muscle = se_taut_ ? std::max(0.0, fid.series_stiffness_nm_per_deg * (th - ce_deg)) : 0.0;
  } else {
    f.muscle = force_gain * activation * joint_.ActiveGain(th, om);  // Eq. 3.16
  }
  f.vol = fid.cocontraction_torque_nm * VoluntaryEnvelope(t_s);
  f.motor = MotorTorque(th, om);
  f.stop = StopTorque(th, om);
  // J·θ̈ = τ_brace − τ_pta − τ_ptv − τ_hyst − τ_fric − τ_muscle − τ_vol (docs/MODEL.md).
  const double net = f.motor + f.stop - f.pta - f.ptv - hyst - f.fric - f.muscle - f.vol;
  f.accel_deg_s2 = RadToDeg(net / joint_.inertia_kgm2());
  return f;
}

double SimulatedBench::SolveCeVelocity(double delta_deg, double h, double drive) const {
  // Backward Euler on Eq. 3.6: K_se·(Δ − h·v) = drive·τ_scale·f_ata(θ_ce)·f_atv(v),
  // left side decreasing and right side non-decreasing in v (f_atv monotone).
  const double kse = subject_.fidelity.series_stiffness_nm_per_deg;
  const double ce = ce_angle_deg_;
  const auto g = [&](double v) { return kse * (delta_deg - h * v) - drive * joint_.ActiveGain(ce, v); };
  double hi = delta_deg / h;  // g(hi) ≤ 0
  double step = std::max(1.0, drive * joint_.ActiveGain(ce, 0.0) / (kse * h));
  double lo = hi - step;
  for (int i = 0; i < 80 && g(lo) < 0.0; ++i) {
    step *= 2.0;
    lo = hi - step;
  }
  for (int i = 0; i < 48; ++i) {
    const double mid = 0.5 * (lo + hi);
    (g(mid) > 0.0 ? lo : hi) = mid;
  }
  const double glo = g(lo), ghi = g(hi);
  return glo == ghi ? 0.5 * (lo + hi) : lo + (hi - lo) * glo / (glo - ghi);
}

void SimulatedBench::SubStep(double h) {
  const Fidelity& fid = subject_.fidelity;
  const double t0 = t_;
  const bool se = fid.series_stiffness_nm_per_deg > 0.0;
  double ce_rate = 0.0;
  if (se) {
    const double f_end = Potentiated(RawActivationAfter(h));
    const double drive = (1.0 - fatigue_) * f_end;
    const double theta_end = lock_engaged_ ? x_[0] : x_[0] + x_[1] * h;
    const double delta = theta_end - ce_angle_deg_;
    se_taut_ = drive * joint_.ActiveGain(ce_angle_deg_, 0.0) > 1e-9;
    ce_rate = se_taut_ ? SolveCeVelocity(delta, h, drive) : delta / h;
  }
  const double ce0 = ce_angle_deg_;
  if (!lock_engaged_) {
    const auto rhs = [&](double t, const State& x) {
      const double f = Potentiated(RawActivationAfter(t - t0));
      const Forces fo = CalcForces(t, x, f, ce0 + ce_rate * (t - t0));
      return State(x[1], fo.accel_deg_s2, fo.hyst_rate);
    };
    x_ = model::Rk4Step(rhs, t0, x_, h);
  }
  if (se) {
    ce_angle_deg_ = ce0 + ce_rate * h;
    ce_velocity_deg_s_ = ce_rate;
  } else {
    ce_angle_deg_ = x_[0];
    ce_velocity_deg_s_ = x_[1];
  }
  chain1_ = primary_.Propagate(chain1_, h);
  if (fid.twitch_variation > 0.0) chain2_ = alternate_.Propagate(chain2_, h);
  t_ = t0 + h;
  // Slow muscle states (§3.3), explicit Euler: seconds-long time constants.
  const double f = RawActivationAfter(0.0);
  if (fid.fatigue_rate_per_s > 0.0 || fatigue_ > 0.0) {
    fatigue_ += h * (fid.fatigue_rate_per_s * f * (1.0 - fatigue_) - fatigue_ / fid.fatigue_recovery_s);
    fatigue_ = std::clamp(fatigue_, 0.0, 0.999);
  }
  if (fid.potentiation_max > 0.0 || potentiation_ > 0.0) {
    potentiation_ += h * (fid.potentiation_rate_per_s * f * (fid.potentiation_max - potentiation_) -
                          potentiation_ / fid.potentiation_decay_s);
    potentiation_ = std::max(potentiation_, 0.0);
  }
}

void SimulatedBench::IntegratePiece(double t_end) {
  const double span = t_end - t_;
  if (!(span > 0.0)) return;
  const bool near_stop = x_[0] < options_.limits.min_angle_deg + kStopZoneDeg ||
                         x_[0] > options_.limits.max_angle_deg - kStopZoneDeg;
  const long n = model::EvenStepCount(span, near_stop ? kStopZoneSubStepS : kMaxSubStepS);
  const double h = span / static_cast<double>(n);
  for (long k = 0; k < n; ++k) SubStep(h);
  t_ = t_end;  // exact end, no round-off drift
}

void SimulatedBench::ControlStepStart() {
  // E-stop: stimulator and motor power cut (the motor falls to kDisabled
  // behaviour in EffectiveMode, a lock opens; FireDuePulses fires nothing).
  if (HardwareEStopped()) lock_engaged_ = false;
  FireDuePulses();  // a grid time exactly where the last AdvanceTo stopped
  if (t_ - setpoint_time_s_ > 2.5 * kControlDtS) setpoint_velocity_deg_s_ = 0.0;
  TryEngageLock();
  if (t_ >= burst_end_s_) ScheduleBursts();
}

void SimulatedBench::TryEngageLock() {
  if (mode_ == MotorMode::kLocked && !lock_engaged_ && !HardwareEStopped() &&
      std::abs(x_[0] - setpoint_deg_) <= kLockToleranceDeg &&
      std::abs(x_[1]) <= kLockVelocityDegS) {
    lock_engaged_ = true;
    x_[0] = setpoint_deg_;
    x_[1] = 0.0;
    ce_angle_deg_ = subject_.fidelity.series_stiffness_nm_per_deg > 0.0 ? ce_angle_deg_ : x_[0];
  }
}

void SimulatedBench::AdvanceTo(double t_target) {
  std::unique_lock lock(mu_);
  while (t_target > t_ + 1e-12) {
    ControlStepStart();
    const double grid_next = static_cast<double>(step_index_ + 1) * kControlDtS;
    const double seg_end = std::min(t_target, grid_next);
    while (t_ < seg_end - 1e-12) {
      // Integration pieces end at every grid time, so a pulse falls between
      // two pieces at its exact time.
      const double next = std::min(seg_end, pulse_clock_.TimeOf(next_grid_k_));
      if (next > t_) IntegratePiece(next);
      // Pulses due at the very end wait for the caller's commands at that
      // time (a stimulator samples its amplitude when it fires).
      if (t_ < t_target - 1e-12) FireDuePulses();
    }
    t_ = std::max(t_, seg_end);
    if (t_ >= grid_next - 1e-12) {
      t_ = std::max(t_, grid_next);
      ++step_index_;
      EmitEmgSample();
    }
    now_s_.store(t_, std::memory_order_release);
    if (options_.on_control_step || pacer_.time_scale() > 0.0) {
      const double t_now = t_;
      lock.unlock();
      pacer_.Pace(t_now);
      if (options_.on_control_step) options_.on_control_step(t_now);
      lock.lock();
    }
  }
  now_s_.store(t_, std::memory_order_release);
}

// --- sensors ----------------------------------------------------------------

double SimulatedBench::Noise(int channel, double t_s) const {
  const auto k = static_cast<std::uint64_t>(std::llround(t_s * 1000.0));
  const std::uint64_t base =
      SplitMix64(noise_seed_ ^ SplitMix64((static_cast<std::uint64_t>(channel) << 48) ^ k));
  const double u1 = UnitUniform(base), u2 = UnitUniform(SplitMix64(base));
  return std::sqrt(-2.0 * std::log1p(-u1)) * std::cos(2.0 * model::kPi * u2);  // Box–Muller
}

double SimulatedBench::HoldingTorque() {
  const double f = Potentiated(RawActivationAfter(0.0));
  const Forces fo = CalcForces(t_, x_, f, ce_angle_deg_);
  // θ̈ = 0: the lock supplies everything else (Eqs. 3.18–3.20 plus extras).
  return fo.pta + fo.ptv + x_[2] + fo.fric + fo.muscle + fo.vol;
}

LegTruth SimulatedBench::Truth() {
  std::lock_guard lock(mu_);
  LegTruth s;
  s.t_s = t_;
  s.angle_deg = x_[0];
  s.velocity_deg_s = x_[1];
  s.activation = Potentiated(RawActivationAfter(0.0));
  const Forces fo = CalcForces(t_, x_, s.activation, ce_angle_deg_);
  s.lock_engaged = lock_engaged_;
  s.accel_deg_s2 = lock_engaged_ ? 0.0 : fo.accel_deg_s2;
  s.ce_angle_deg = ce_angle_deg_;
  s.muscle_torque_nm = fo.muscle;
  s.motor_torque_nm = lock_engaged_ ? HoldingTorque() : fo.motor;
  s.brace_torque_nm = lock_engaged_ ? s.motor_torque_nm
                                    : (EffectiveMode() == MotorMode::kDecoupled ? 0.0 : fo.motor) +
                                          fo.stop;
  s.fatigue = fatigue_;
  s.potentiation = potentiation_;
  s.hysteresis_nm = x_[2];
  s.voluntary_nm = fo.vol;
  return s;
}

SensorFrame SimulatedBench::ReadSensors() {
  const LegTruth truth = Truth();
  std::lock_guard lock(mu_);
  const Fidelity& fid = subject_.fidelity;
  SensorFrame frame;
  frame.t_s = t_;
  // Potentiometer: periodic non-linearity per turn, zero at 90° (§5.1).
  double angle = truth.angle_deg +
                 fid.pot_nonlinearity * kPotTurnDeg *
                     std::sin(2.0 * model::kPi * (truth.angle_deg - 90.0) / kPotTurnDeg) +
                 fid.angle_noise_deg * Noise(kNoiseAngle, t_);
  if (fid.quantise_adc) angle = Quantise(angle, kAngleLsbDeg, kAngleMidScaleDeg);
  frame.angle_deg = angle;
  // Strain gauge, always through the 12-bit A/D (0.0381 N·m/LSB, ±78 N·m).
  frame.torque_nm =
      Quantise(truth.brace_torque_nm + fid.torque_noise_nm * Noise(kNoiseTorque, t_), kTorqueLsbNm);
  // Tangential accelerometer at d with gravity (positive towards flexion).
  double accel = subject_.anthropometrics.accel_distance_m * DegToRad(truth.accel_deg_s2) +
                 kStandardGravity_m_s2 * std::sin(DegToRad(truth.angle_deg - hang_deg_)) +
                 fid.accel_noise_m_s2 * Noise(kNoiseAccel, t_);
  if (fid.quantise_adc) accel = Quantise(accel, kAccelLsbM_s2);
  frame.accel_m_s2 = accel;
  const double period_s = 1.0 / options_.limits.pulse_rate_hz;
  frame.stim_ma = (!HardwareEStopped() && t_ - last_pulse_t_s_ < period_s + 1e-6) ? last_pulse_ma_ : 0.0;
  frame.limit_flexion = truth.angle_deg >= options_.limits.max_angle_deg - kLimitSwitchMarginDeg;
  frame.limit_extension = truth.angle_deg <= options_.limits.min_angle_deg + kLimitSwitchMarginDeg;
  frame.estop = HardwareEStopped();
  frame.subject_limit = frame.stim_ma >= subject_.max_tolerated_ma;  // max tolerated > 0
  return frame;
}

void SimulatedBench::EmitEmgSample() {
  const Fidelity& fid = subject_.fidelity;
  double v = fid.emg_noise_mv * Noise(kNoiseEmg, t_);
  const double since = t_ - last_pulse_t_s_;
  if (fid.emg_m_wave_mv > 0.0 && since >= 0.0 && since < kMWaveSpanS) {
    v += fid.emg_m_wave_mv * last_pulse_r_ * (1.0 - fatigue_) *
         std::sin(2.0 * model::kPi * since / kMWavePeriodS) * std::exp(-since / kMWaveDecayS);
  }
  const double env = VoluntaryEnvelope(t_);
  if (env > 0.0) v += fid.cocontraction_emg_mv * env * Noise(kNoiseBurstEmg, t_);
  if (emg_.size() >= kMaxEmgSamples) emg_.erase(emg_.begin(), emg_.begin() + kMaxEmgSamples / 2);
  emg_.push_back(v);
}

std::vector<double> SimulatedBench::DrainEmg_mv() {
  std::lock_guard lock(mu_);
  std::vector<double> out;
  out.swap(emg_);
  return out;
}

model::PulseTrain SimulatedBench::DeliveredPulses() {
  std::lock_guard lock(mu_);
  return delivered_;
}

std::vector<model::Pulse> SimulatedBench::DrainDeliveredPulses() {
  std::lock_guard lock(mu_);
  std::vector<model::Pulse> out;
  out.swap(readback_);
  return out;
}

}  // namespace fesbench::server
