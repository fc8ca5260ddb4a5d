#pragma once

/// @file
/// Active identification (thesis §4.3, §5.4.4, §6.7–6.8): f_ata(θ), f_atv(θ̇)
/// and τ_scale by least squares in the log domain (Eq. 4.40) from a
/// free-swing trial under stimulation, for one passive parameter set
/// (call once per passive set, §5.4.4).
///
/// Trials need t_s, angle_deg, velocity_deg_s, accel_deg_s2 and activation
/// (f_stim, e.g. from ActivationAt with the identified IRC and contraction
/// dynamics); torque_nm is used only with use_measured_torque.

#include <span>
#include <vector>

#include "model/identify_common.h"
#include "model/parameter_set.h"

namespace fesbench::model {

/// The active torque implied by the kinematics and a passive set (Eq. 4.38):
/// τ_act = τ_motor − J·θ̈ − τ_pta(θ) − τ_ptv(θ̇), τ_motor = torque_nm when
/// use_measured_torque (motor trials) and 0 in free swing. N·m.
/// @throws std::invalid_argument on missing columns or empty passive curves.
std::vector<double> ActiveTorque(const TrialColumns& trial, const PassiveParams& passive,
                                 bool use_measured_torque = false);

/// Options of IdentifyActive.
struct ActiveOptions {
  BreakpointSpec angle{11, {}};      ///< f_ata breakpoints (§7.4.4: 11).
  BreakpointSpec velocity{11, {}};   ///< f_atv breakpoints (§7.4.4: 11).
  double min_activation = 0.01;      ///< §5.4.4: samples with f_stim ≥ 0.01.
  bool use_measured_torque = false;  ///< motor trials: τ_motor from torque_nm.
  double relative_tolerance = 1e-10;
  double min_support = 1.0;
  double coverage_warn_below = 0.25;
  /// Smoothness of ln f_ata and ln f_atv (beyond the thesis): rows
  /// √(smoothness·N)·(c_{j−1} − 2c_j + c_{j+1}) = 0 for every interior
  /// breakpoint of either curve (N the active samples), so a bend of one
  /// log unit costs as much as raising the mean squared log residual by
  /// `smoothness`. Keeps sparsely supported breakpoints (e.g. 90°, visited
  /// only at the onset of a burst) from bumps no muscle has (≥ 0; 0 = off).
  double smoothness = 0.0;
};

/// An active parameter set with its report.
struct ActiveResult {
  ActiveParams active;
  IdentifyReport report;
};

/// Eq. 4.40: log(τ_act / f_stim) = Σ c_j X_j(θ) + Σ c_k X_k(θ̇) + log τ_scale
/// on the samples with f_stim ≥ min_activation and τ_act > 0, solved by
/// truncated SVD; ordinates returned to the real domain by exp (Fig. 4-2)
/// and normalised to f_ata(90°) = f_atv(0) = 1 with the factors moved into
/// τ_scale (§6.7). fit_rms has "active_log" (log units) and "active_nm"
/// (τ_act error of the fitted curves, N·m).
/// @throws std::invalid_argument on missing columns or fewer usable samples
///   than parameters.
ActiveResult IdentifyActive(std::span<const TrialColumns> trials, const PassiveParams& passive,
                            const ActiveOptions& options = {});

}  // namespace fesbench::model
