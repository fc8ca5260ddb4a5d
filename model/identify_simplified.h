#pragma once

/// @file
/// Fits of the model variants (docs/MODEL.md, "Model variants"; thesis §5.5.1, §6.10, §7.3,
/// §7.4.4) from the same free-swing active trial as the full model, with
/// the passive set (and IRC, contraction) of a base parameter set.
///
///  - torque_generator: f_ata = f_atv = 1; τ_scale by linear least squares
///    of τ_act = τ_scale·f_stim.
///  - single_segment: τ_act = τ_scale·f_stim·(aθ + b)(cθ̇ + d) (Eqs. 5.1–5.2)
///    by alternating linear least squares (each factor is linear with the
///    other fixed), normalised to (a·90 + b) = 1 and d = 1.
///  - static_gain_pwl_velocity: τ_act = f_stim·Σ c_k X_k(θ̇), linear in the
///    real domain; τ_scale = the curve at 0 deg/s, f_atv normalised (§7.3).
///  - parametric: τ_pta of Eq. 7.3 fitted to the base τ_pta curve (variable
///    projection over k₂); Gaussian f_ata and two-segment f_atv (§7.4.4) by
///    alternating least squares (log-domain quadratic for the Gaussian,
///    linear for the two slopes).
///  - full: IdentifyActive (Eq. 4.40).
/// Trials need the columns IdentifyActive needs.

#include <span>

#include "model/identify_active.h"
#include "model/identify_common.h"
#include "model/parameter_set.h"

namespace fesbench::model {

/// Options of IdentifySimplified.
struct SimplifiedOptions {
  ActiveOptions active;             ///< sample selection; breakpoints of full.
  BreakpointSpec velocity{11, {}};  ///< f_atv breakpoints of static_gain_pwl_velocity.
  int iterations = 50;              ///< alternating least-squares sweeps.
};

/// A variant's parameter set (base with the variant's fields replaced and
/// `model` set) and its report (fit_rms "<variant>_nm": τ_act error).
struct SimplifiedResult {
  ParameterSet params;
  IdentifyReport report;
};

/// Fits variant `kind` to the trials on top of `base` (whose passive set
/// computes τ_act, Eq. 4.38).
/// @throws std::invalid_argument on missing columns, no usable active
///   samples, or empty passive curves in base.
SimplifiedResult IdentifySimplified(ModelKind kind, std::span<const TrialColumns> trials,
                                    const ParameterSet& base,
                                    const SimplifiedOptions& options = {});

/// Eq. 7.3 fitted to a τ_pta curve: mgl·sin θ + k₁·e^(k₂θ) + offset, θ in
/// rad, on 1° samples over the curve's breakpoint range; RMS in N·m.
/// @throws std::invalid_argument if the curve has fewer than 2 breakpoints.
ParametricParams FitParametricTorqueAngle(const PiecewiseLinear& torque_angle, double* rms_nm);

}  // namespace fesbench::model
