#pragma once

/// @file
/// The simulated bench (docs/ARCHITECTURE.md, "The benches"): a virtual leg on a virtual knee
/// bench, deliberately richer than the identification model (virtual_subject.h).
///
/// Physics (θ in degrees of flexion, torques + flexion, docs/ARCHITECTURE.md):
///   J·θ̈ = τ_brace − τ_pta(θ) − τ_ptv(θ̇) − τ_hyst − τ_fric − τ_muscle − τ_vol
/// with τ_brace = τ_motor + τ_stop, θ̈ in rad/s².
/// - Stimulator: a continuous pulse clock (model::PulseClock, docs/MODEL.md)
///   restarted by RestartPulseClock (at bench start and by the runner at each
///   trial's start); every grid time at which the amplitude is > 0 fires a
///   pulse of that amplitude (model::PulsesFromEnvelope's rule); TriggerPulse
///   fires one now, off the grid. Each pulse is an impulse of weight
///   R(u)/f_pulse into H_n (docs/MODEL.md), propagated exactly between events;
///   with twitch variation a fraction goes to a chain of the other order
///   peaking at the same time (Fig. 3-8).
/// - Muscle: τ_muscle = (1 − F)·f·τ_scale·f_ata·f_atv (Eq. 3.16), f the
///   potentiated activation. With series elasticity, the CE is massless
///   (Eqs. 3.5–3.6, with Eqs. 3.7–3.9's slack SE when unstimulated); its
///   angle is advanced by backward Euler, solving
///   K_se·(θ − θ_ce) = (1 − F)·f·τ_scale·f_ata(θ_ce)·f_atv(θ̇_ce) for θ̇_ce.
/// - Passive: Dahl-type hysteresis (Fig. 3-7) and regularised static friction.
/// - Motor: kLocked = rigid at the set-point once reached (moved there by the
///   servo first), torque channel = holding torque; kPosition = PD servo
///   (with set-point velocity feed-forward) limited to 50 N·m; kDecoupled =
///   free swing; kDisabled = coupled, unpowered gearbox drag. Limit switches
///   2° inside each stop forbid motor torque towards that stop. Hard stops
///   at 10° and 110° are stiff one-sided spring–dampers (10⁴ N·m/deg:
///   < 0.01° under a steady 60 N·m, a few tenths of a degree when the leg
///   strikes at 600 deg/s; sub-steps of 0.1 ms within 5° of a stop).
/// - Sensors: potentiometer (1 % non-linearity, 120°/turn), strain-gauge
///   torque (12-bit, 0.0381 N·m/LSB, ±78 N·m), calf accelerometer at
///   accel_distance_m, EMG at 1 kHz (noise, M-waves, voluntary bursts).
///   Noise is a function of (seed, channel, millisecond), so a stream does
///   not depend on how often it is read.
/// - Accelerometer: tangential, positive in the flexion direction. The thigh
///   is elevated `thigh_elevation_deg` above horizontal (the subject
///   reclines, Fig. 5-5), so the shank hangs vertically at 90° − elevation;
///   reading = d·θ̈ + g·sin(θ − θ_hang) (gravity seen by the sensor).
/// - Time: AdvanceTo integrates in 1 ms control steps (RK4 sub-steps of at
///   most 0.5 ms, cut at every pulse), paced to time_scale × real time
///   (0 = as fast as possible).
///
/// Threading: HardwareEStop, ClearHardwareEStop, HardwareEStopped and Now_s
/// may be called from any thread at any time and never block; the e-stop
/// takes effect at the next control step (≤ 1 ms of bench time). The other
/// methods are serialised by an internal mutex that AdvanceTo releases between
/// control steps and while it sleeps.

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <vector>

#include <Eigen/Core>

#include "api/status.h"
#include "model/contraction.h"
#include "model/joint_model.h"
#include "model/signal.h"
#include "server/bench/bench.h"
#include "server/bench/pacer.h"
#include "server/bench/virtual_subject.h"

namespace fesbench::server {

struct SimulatedBenchOptions {
  BenchLimits limits;
  double time_scale = 0.0;        ///< bench s per wall s; 0 = as fast as possible.
  std::uint64_t seed = 1;         ///< combined with the subject's seed.
  api::Clock* clock = api::Clock::Real();  ///< paces the bench; outlives it.
  /// Initial knee angle; unset = the passive rest angle (τ_pta + τ_ptv(0) = 0),
  /// or 90° if there is none in range.
  std::optional<double> initial_angle_deg;
  MotorMode initial_mode = MotorMode::kDisabled;
  /// Initial set-point (lock angle); unset = the initial angle.
  std::optional<double> initial_setpoint_deg;
  /// Called after every 1 ms control step with the bench time, outside the
  /// bench's lock (tests use it to act "during" AdvanceTo).
  std::function<void(double)> on_control_step;
};

/// Ground truth of the virtual leg (not what the sensors report).
struct LegTruth {
  double t_s = 0.0;
  double angle_deg = 0.0;
  double velocity_deg_s = 0.0;
  double accel_deg_s2 = 0.0;
  double activation = 0.0;        ///< potentiated f_stim.
  double ce_angle_deg = 0.0;      ///< contractile element angle (= θ without SE).
  double muscle_torque_nm = 0.0;  ///< extensor torque of the stimulated muscle.
  double brace_torque_nm = 0.0;   ///< unquantised, noise-free torque channel.
  double motor_torque_nm = 0.0;
  double fatigue = 0.0;           ///< F in [0, 1).
  double potentiation = 0.0;      ///< P ≥ 0.
  double hysteresis_nm = 0.0;
  double voluntary_nm = 0.0;
  bool lock_engaged = false;
};

class SimulatedBench final : public Bench {
 public:
  /// The bench for `subject`, or kInvalidArgument (naming the field) if it
  /// fails ValidateVirtualSubject.
  static api::Result<std::unique_ptr<SimulatedBench>> Create(VirtualSubject subject,
                                                             SimulatedBenchOptions options = {});
  ~SimulatedBench() override;

  std::string_view kind() const override { return "sim"; }
  const BenchLimits& limits() const override { return options_.limits; }

  void SetStimAmplitude(double stim_ma) override;
  void TriggerPulse(double stim_ma) override;
  void RestartPulseClock() override;
  std::vector<model::Pulse> DrainDeliveredPulses() override;
  void SetMotorMode(MotorMode mode) override;
  void SetMotorSetpoint(double angle_deg) override;

  double Now_s() const override { return now_s_.load(std::memory_order_acquire); }
  void AdvanceTo(double t_s) override;

  SensorFrame ReadSensors() override;
  std::vector<double> DrainEmg_mv() override;

  void HardwareEStop() override { estop_.store(true, std::memory_order_release); }
  void ClearHardwareEStop() override { estop_.store(false, std::memory_order_release); }
  bool HardwareEStopped() const override { return estop_.load(std::memory_order_acquire); }

  /// Changes the pacing (re-anchors the wall clock).
  void set_time_scale(double time_scale);
  const VirtualSubject& subject() const { return subject_; }
  LegTruth Truth();
  /// Every pulse the stimulator delivered (time, amplitude), in order (the
  /// oldest half is dropped beyond 10⁶ pulses, ~8 h at 33 Hz). Unlike
  /// DrainDeliveredPulses, reading does not consume.
  model::PulseTrain DeliveredPulses();

 private:
  // `subject` has passed ValidateVirtualSubject (Create checks it).
  SimulatedBench(VirtualSubject subject, SimulatedBenchOptions options);

  using State = Eigen::Matrix<double, 3, 1>;  // θ (deg), θ̇ (deg/s), τ_hyst (N·m)
  struct Forces;

  void FirePulse(double stim_ma);
  void FireDuePulses();
  void ControlStepStart();
  void TryEngageLock();
  void IntegratePiece(double t_end);
  void SubStep(double h);
  double RawActivationAfter(double dt_s);
  double Potentiated(double f_raw) const;
  double VoluntaryEnvelope(double t_s) const;
  double MotorTorque(double angle_deg, double velocity_deg_s) const;
  double StopTorque(double angle_deg, double velocity_deg_s) const;
  Forces CalcForces(double t_s, const State& x, double activation, double ce_deg) const;
  double SolveCeVelocity(double delta_deg, double h, double drive) const;
  double HoldingTorque();
  void EmitEmgSample();
  void ScheduleBursts();
  MotorMode EffectiveMode() const;
  double Noise(int channel, double t_s) const;

  VirtualSubject subject_;
  SimulatedBenchOptions options_;
  model::JointModel joint_;
  Pacer pacer_;
  std::mutex mu_;
  std::atomic<bool> estop_{false};
  std::atomic<double> now_s_{0.0};

  // Time.
  double t_ = 0.0;
  std::int64_t step_index_ = 0;  // control steps completed.
  static constexpr double kControlDtS = 1e-3;
  static constexpr double kMaxSubStepS = 5e-4;

  // Stimulator.
  double commanded_ma_ = 0.0;
  model::PulseClock pulse_clock_;
  std::int64_t next_grid_k_ = 0;  // the next grid time not yet passed
  double last_pulse_t_s_ = -1e9;
  double last_pulse_ma_ = 0.0;
  double last_pulse_r_ = 0.0;
  model::PulseTrain delivered_;
  std::vector<model::Pulse> readback_;  // since the last DrainDeliveredPulses

  // Contraction chains (primary order n and the same-peak alternate).
  model::ContractionPropagator primary_, alternate_;
  model::ContractionState chain1_{}, chain2_{};
  double fatigue_ = 0.0, potentiation_ = 0.0;

  // Mechanics.
  State x_ = State::Zero();
  double ce_angle_deg_ = 0.0;
  double ce_velocity_deg_s_ = 0.0;
  bool se_taut_ = false;  // the SE carries the CE's torque (else slack, Eq. 3.8).
  double hang_deg_ = 81.0;

  // Motor.
  MotorMode mode_ = MotorMode::kDisabled;
  double setpoint_deg_ = 90.0;
  double setpoint_velocity_deg_s_ = 0.0;
  double setpoint_time_s_ = 0.0;
  bool lock_engaged_ = false;

  // Voluntary co-contraction bursts and EMG.
  std::mt19937_64 burst_rng_;
  double burst_start_s_ = 1e300, burst_end_s_ = 1e300;
  std::uint64_t noise_seed_ = 0;
  std::vector<double> emg_;
};

}  // namespace fesbench::server
