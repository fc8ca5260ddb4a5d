#pragma once

/// @file
/// Signal conditioning before identification (thesis §5.1, §5.3, §5.4.1):
/// torque offset removal, the accelerometer's gravity calibration table
/// from position holds, and differentiation of position by a cubic
/// smoothing spline whose smoothing is chosen by generalised
/// cross-validation (Woltring's GCVSPL, §5.1; Woltring 1986).

#include <cstddef>
#include <span>
#include <vector>

#include "model/piecewise_linear.h"

namespace fesbench::model {

/// Mean of the first `count` samples: the offset measured immediately
/// before a trial (§5.3: "sampled 50 times … averaged and recorded as an
/// offset").
/// @throws std::invalid_argument if count == 0 or torque has fewer samples.
double TorqueOffset(std::span<const double> torque_nm, std::size_t count = 50);

/// torque − TorqueOffset(torque, count).
std::vector<double> RemoveTorqueOffset(std::span<const double> torque_nm, std::size_t count = 50);

/// One static position hold found in a motor trial (§5.4.1).
struct PositionHold {
  std::size_t begin = 0;      ///< first sample of the hold.
  std::size_t end = 0;        ///< one past its last sample.
  double angle_deg = 0.0;     ///< mean of the last `average_samples` samples.
  double torque_nm = 0.0;     ///< same window (NaN if no torque column).
  double accel_deg_s2 = 0.0;  ///< same window (NaN if no accel column).
};

/// Options of DetectHolds.
struct HoldOptions {
  double max_speed_deg_s = 0.5;      ///< |Δθ/Δt| below this counts as still.
  /// Δθ/Δt is taken across this span centred on each sample, so that
  /// potentiometer noise and A/D steps (±0.03° at 200 Hz would read as
  /// several deg/s between neighbours) do not hide a hold.
  double speed_span_s = 0.5;
  double min_duration_s = 1.0;       ///< shorter still runs are not holds.
  std::size_t average_samples = 50;  ///< §5.4.1: 50 samples averaged.
};

/// Finds runs where the knee is still (speed over speed_span_s below
/// max_speed_deg_s) for at least min_duration_s, and averages angle, torque
/// and acceleration over the last `average_samples` samples of each.
/// torque_nm and accel_deg_s2 may be empty.
/// @throws std::invalid_argument if t_s and angle_deg differ in length or
///   have fewer than 2 samples, a non-empty column has another length, or
///   average_samples == 0.
std::vector<PositionHold> DetectHolds(std::span<const double> t_s,
                                      std::span<const double> angle_deg,
                                      std::span<const double> torque_nm,
                                      std::span<const double> accel_deg_s2,
                                      const HoldOptions& options = {});

/// Merges holds at the same angle (within tolerance_deg) visited in both
/// directions by averaging their readings (§5.4.1), returning the points
/// sorted by angle. `value` selects torque (false) or acceleration (true).
/// @throws std::invalid_argument if holds is empty.
PiecewiseLinear AverageHoldsByAngle(std::span<const PositionHold> holds, bool acceleration,
                                    double tolerance_deg = 0.5);

/// The accelerometer gravity calibration table (§5.1, Appendix C): the
/// accelerometer reading, deg/s², at rest as a function of angle, from the
/// position holds of a motor trial, both directions averaged.
/// @throws std::invalid_argument as DetectHolds, or if no hold is found.
PiecewiseLinear AccelerometerCalibration(std::span<const double> t_s,
                                         std::span<const double> angle_deg,
                                         std::span<const double> accel_deg_s2,
                                         const HoldOptions& options = {});

/// Removes gravity from an accelerometer signal (§5.1):
/// θ̈ = reading − table(θ).
/// @throws std::invalid_argument if the columns differ in length or the
///   table is empty.
std::vector<double> CorrectAcceleration(const PiecewiseLinear& calibration,
                                        std::span<const double> angle_deg,
                                        std::span<const double> accel_deg_s2);

/// A cubic (order 2m, m = 2) natural smoothing spline through noisy samples
/// and its first two derivatives at the sample times.
struct SmoothingSplineFit {
  std::vector<double> value;   ///< smoothed samples, input unit.
  std::vector<double> first;   ///< d/dt at each sample, unit/s.
  std::vector<double> second;  ///< d²/dt² at each sample, unit/s².
  double lambda = 0.0;         ///< smoothing parameter used.
  double gcv = 0.0;            ///< GCV criterion at lambda.
  double residual_rms = 0.0;   ///< rms(y − value).
  double effective_dof = 0.0;  ///< tr(A(λ)), the fit's degrees of freedom.
};

/// The cubic smoothing spline minimising Σ (y_i − f(t_i))² + λ ∫ f''(t)² dt
/// for a given λ (Reinsch's banded formulation, O(n)).
/// @throws std::invalid_argument if fewer than 4 samples, the sizes differ,
///   t is not strictly increasing, a value is not finite, or lambda < 0.
SmoothingSplineFit SmoothingSpline(std::span<const double> t_s, std::span<const double> y,
                                   double lambda);

/// Woltring's GCVSPL mode (§5.1; Woltring 1986): λ chosen to minimise the
/// generalised cross-validation criterion
///   GCV(λ) = n · RSS(λ) / tr(I − A(λ))²,
/// A(λ) the spline's influence matrix, whose trace is computed exactly in
/// O(n) from the band of the inverse of the Reinsch matrix (Hutchinson &
/// de Hoog 1985). The search is over log λ (coarse grid then golden
/// section). Throws as SmoothingSpline.
SmoothingSplineFit GcvSmoothingSpline(std::span<const double> t_s, std::span<const double> y);

}  // namespace fesbench::model
