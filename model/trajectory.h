#pragma once

/// @file
/// Prescribed knee trajectories for motor mode (thesis §4.2.2, §5.4.1–5.4.2;
/// docs/PROTOCOLS.md passive_sequential and passive_simultaneous), with a
/// name-based registry like the stimulus one (model/stimulus_generators.h).
///
/// Registry names:
///  - sum_of_sines: the seeded pseudo-random sum of six sines (§4.2.2
///    "Generating/choosing appropriate inputs", Fig. 5-9).
///  - passive_positions: the step-wise position measurements of §5.4.1.
///  - passive_velocities: the constant-velocity measurements of §5.4.1.

#include <array>
#include <cstdint>
#include <memory>
#include <string_view>
#include <vector>

#include "model/signal.h"
#include "model/stimulus_generators.h"

namespace fesbench::model {

/// Options of the sum-of-sines trajectory.
///
/// Design (§4.2.2: "a sum of six sine waves with random (although limited)
/// frequency and phase"): g(t) = Σᵢ aᵢ·sin(2π fᵢ t + φᵢ) with fᵢ uniform in
/// [min_frequency_hz, max_frequency_hz], φᵢ uniform in [0, 2π) and aᵢ uniform
/// in [0.5, 1] (std::mt19937_64(seed), 53-bit conversion: identical on every
/// platform). A fade w(t) — the quintic smoothstep 10u³ − 15u⁴ + 6u⁵ over the
/// first and last fade_s, 1 in between — gives x = w·g, which starts and
/// ends with zero velocity and acceleration, so the motor starts and stops at
/// rest. The angle is θ(t) = c + s·x(t), with s and c chosen so θ spans
/// [min_deg, max_deg] unless the speed limit binds first:
/// s = 0.999·min((max − min)/(x_max − x_min), v_max/max|ẋ|) (extremes from a
/// 10 kHz grid; the 0.1 % margin covers the grid error) and c centres
/// [x_min, x_max] in the range. Velocity and acceleration are analytic
/// (product rule); outside [0, duration_s] the end angles are held at rest.
struct SumOfSinesOptions {
  double min_deg = 30.0;              ///< lower angle limit, deg.
  double max_deg = 100.0;             ///< upper angle limit, deg (> min_deg).
  double max_velocity_deg_s = 200.0;  ///< |θ̇| limit, deg/s (> 0).
  double duration_s = 10.0;           ///< length, s (> 2·fade_s).
  double fade_s = 1.0;                ///< fade-in/out length, s (> 0).
  int sines = 6;                      ///< number of components (≥ 1).
  double min_frequency_hz = 0.1;      ///< lowest component frequency (> 0).
  double max_frequency_hz = 1.0;      ///< highest component frequency (≥ min).
  std::uint64_t seed = 1;
};

/// One component aᵢ·sin(2π fᵢ t + φᵢ) of g(t) (before scaling).
struct SineComponent {
  double amplitude = 0.0;
  double frequency_hz = 0.0;
  double phase_rad = 0.0;
};

/// The seeded sum-of-sines trajectory (see SumOfSinesOptions).
class SumOfSinesTrajectory final : public Trajectory {
 public:
  /// @throws std::invalid_argument if an option breaks its stated range.
  explicit SumOfSinesTrajectory(const SumOfSinesOptions& options);
  Kinematics At(double t_s) const override;
  double duration_s() const override { return options_.duration_s; }

  const std::vector<SineComponent>& components() const { return components_; }
  /// s: degrees per unit of x.
  double scale_deg() const { return scale_deg_; }
  /// c: the angle at x = 0 (also the start and end angle), deg.
  double centre_deg() const { return centre_deg_; }

 private:
  // x = w·g and its first and second time derivatives.
  std::array<double, 3> Unscaled(double t_s) const;

  SumOfSinesOptions options_;
  std::vector<SineComponent> components_;
  double scale_deg_ = 0.0;
  double centre_deg_ = 0.0;
};

/// A trajectory made of contiguous polynomial pieces
/// θ(τ) = Σⱼ cⱼ τʲ (τ = t − start_s, j = 0..5, deg and s). Outside the pieces
/// the first/last angle is held with zero velocity and acceleration.
class PiecewisePolynomialTrajectory final : public Trajectory {
 public:
  struct Piece {
    double start_s = 0.0;
    double duration_s = 0.0;
    std::array<double, 6> coefficients{};  ///< c₀..c₅ in deg/sʲ.
  };
  /// @throws std::invalid_argument if pieces is empty, the first does not
  ///   start at 0, a piece has a non-positive duration or they are not
  ///   contiguous (gap or overlap above 1 µs).
  explicit PiecewisePolynomialTrajectory(std::vector<Piece> pieces);
  Kinematics At(double t_s) const override;
  double duration_s() const override;
  const std::vector<Piece>& pieces() const { return pieces_; }

 private:
  std::vector<Piece> pieces_;
};

/// A time window of a trajectory where a passive property is measured: a
/// hold at angle_deg (velocity 0) or a constant-velocity move at
/// velocity_deg_s (angle_deg = angle at the window start).
struct MeasurementWindow {
  double start_s = 0.0;
  double end_s = 0.0;
  double angle_deg = 0.0;
  double velocity_deg_s = 0.0;
};

/// A trajectory with the windows the sequential identification uses.
struct SequentialPlan {
  PiecewisePolynomialTrajectory trajectory;
  std::vector<MeasurementWindow> windows;
};

/// §5.4.1 step-wise positions. Timeline: hold start_deg for reference_s
/// (offset torque); then `positions` angles evenly spaced from max_deg down
/// to min_deg and the same angles back up (2·positions holds), each reached
/// by a minimum-jerk move (10u³ − 15u⁴ + 6u⁵) of move_s and held for hold_s
/// (a zero-length move at the turn is a plain hold); finally a move_s move
/// back to start_deg. One window per hold (its whole hold_s).
/// Defaults: 10 + 40·(1 + 10) + 1 = 451 s.
struct PassivePositionsOptions {
  double start_deg = 90.0;    ///< reference angle, deg.
  double max_deg = 110.0;     ///< first (largest flexion) angle, deg.
  double min_deg = 30.0;      ///< full extension for the subject, deg (< max_deg).
  int positions = 20;         ///< ≥ 2.
  double hold_s = 10.0;       ///< > 0.
  double move_s = 1.0;        ///< > 0.
  double reference_s = 10.0;  ///< ≥ 0.
};
/// @throws std::invalid_argument if an option breaks its stated range.
SequentialPlan PassivePositions(const PassivePositionsOptions& options);

/// §5.4.1 constant velocities. For each speed vₖ = k·max_speed/speeds
/// (k = 1..speeds): pause_s at reference_deg (offset torque), an extension
/// move at −vₖ, pause_s, the mirror flexion move at +vₖ back to
/// reference_deg. A move is a smooth acceleration over accel_s (velocity
/// v·(3u² − 2u³)), constant velocity for constant_s, a smooth stop over
/// decel_s; the motor accelerates during the first part (thesis: "the first
/// one second", not used) and the window is the constant part.
/// A move covers v·(accel_s/2 + constant_s + decel_s/2) degrees.
/// Defaults: 8 speeds up to 30 deg/s, 1 + 1 + 0.5 s moves, 10 s pauses: 200 s.
struct PassiveVelocitiesOptions {
  double reference_deg = 90.0;    ///< deg.
  double min_deg = 30.0;          ///< the extension moves must stay ≥ this, deg.
  int speeds = 8;                 ///< ≥ 1.
  double max_speed_deg_s = 30.0;  ///< > 0.
  double accel_s = 1.0;           ///< > 0.
  double constant_s = 1.0;        ///< > 0.
  double decel_s = 0.5;           ///< > 0.
  double pause_s = 10.0;          ///< ≥ 0.
};
/// @throws std::invalid_argument if an option breaks its stated range or the
///   fastest move would pass below min_deg (names max_speed_deg_s).
SequentialPlan PassiveVelocities(const PassiveVelocitiesOptions& options);

/// Every trajectory generator. Parameters: sum_of_sines: min_deg, max_deg,
/// max_velocity_deg_s, duration_s, fade_s, sines, min_frequency_hz,
/// max_frequency_hz, seed; passive_positions and passive_velocities: the
/// fields of their options structs (same names).
const std::vector<GeneratorDescription>& TrajectoryGenerators();

/// The trajectory generator called name, or nullptr.
const GeneratorDescription* FindTrajectoryGenerator(std::string_view name);

/// Builds trajectory name with params (defaults for missing ones).
/// @throws std::invalid_argument for an unknown name or a bad parameter,
///   naming it (see ResolveParameters).
std::unique_ptr<Trajectory> MakeTrajectory(std::string_view name,
                                           const GeneratorParams& params = {});

/// A trajectory sampled at rate_hz from t = 0 to duration_s inclusive
/// (floor(duration·rate) + 1 samples): the columns angle_deg,
/// velocity_deg_s, accel_deg_s2.
struct TrajectorySamples {
  double rate_hz = 200.0;
  std::vector<double> angle_deg;
  std::vector<double> velocity_deg_s;
  std::vector<double> accel_deg_s2;
};

/// @throws std::invalid_argument if rate_hz is not positive and finite.
TrajectorySamples SampleTrajectory(const Trajectory& trajectory, double rate_hz = 200.0);

}  // namespace fesbench::model
