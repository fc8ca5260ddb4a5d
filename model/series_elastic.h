#pragma once

/// @file
/// Simulator-only series-elastic variant of the model (thesis §3.1,
/// Figs. 3-2, 3-3, Eqs. 3.11–3.14; §6.4): the contractile element (CE)
/// drives a small inertia m that pulls on the joint through a linear series
/// elastic element (SE) of stiffness K_se. Used to show how series
/// compliance delays and reshapes the isometric twitch (§6.4.1, Figs.
/// 6-13, 6-14); identification always assumes the rigid model.
///
/// Sign conventions adapted to fesbench's (docs/ARCHITECTURE.md, units): angles in degrees
/// of flexion, torques positive in flexion, τ_pta and τ_ptv resisting torques
/// as in Eq. 4.9 (the thesis's Eq. 3.14 adds them, with its own signs), and
/// the CE an extensor. With θ_ce the CE's angle coordinate (deg), the SE
/// transmits the extensor torque
///   τ_se = K_se·(θ − θ_ce) + B_se·(θ̇ − θ̇_ce),
/// and (θ̈ in rad/s², converted from deg only via units.h)
///   m·θ̈_ce = τ_se − τ_scale·f_stim·f_ata(θ_ce)·f_atv(θ̇_ce)        (Eq. 3.12)
///   J·θ̈    = τ_motor − τ_pta(θ) − τ_ptv(θ̇) − τ_se                  (Eq. 3.14)
/// As K_se → ∞, θ_ce → θ and the rigid model of simulate.h is recovered
/// (with J + m as the inertia). B_se is an optional extension (default 0, as
/// in the thesis); without it the CE mass is undamped while f_stim = 0.
/// The system is stiff for large K_se/m: use the adaptive integrator (the
/// default here) or an RK4 step well below 2/√(K_se/m).

#include <vector>

#include "model/parameter_set.h"
#include "model/signal.h"
#include "model/simulate.h"

namespace fesbench::model {

/// Series-elastic element and CE mass.
struct SeriesElasticParams {
  double kse_nm_per_deg = 35.0;          ///< K_se > 0, N·m/deg (§6.4: 4, 35, 1000).
  double ce_inertia_kgm2 = 1e-3;         ///< m > 0, kg·m², small against J.
  double se_damping_nm_s_per_deg = 0.0;  ///< B_se ≥ 0, N·m·s/deg.
};

/// A series-elastic simulation: the joint columns as in SimulationResult
/// (torque_nm is the brace torque: 0 in free swing, τ_pta(θ₀) + τ_ptv(0) +
/// τ_se when isometric) plus the CE state and the SE torque.
struct SeriesElasticResult {
  SimulationResult joint;
  std::vector<double> ce_angle_deg;
  std::vector<double> ce_velocity_deg_s;
  std::vector<double> se_torque_nm;  ///< τ_se, N·m (extensor positive).
};

/// Options defaulting to the adaptive integrator with tight tolerances.
SimulationOptions DefaultSeriesElasticOptions();

/// Free swing with the SE (CE starts at θ(0) with θ̇(0), the SE unloaded).
/// @throws std::invalid_argument as SimulateFreeSwing, and if K_se or m is
///   not finite and > 0 or B_se is negative or not finite.
/// @throws std::runtime_error if the adaptive integrator fails.
SeriesElasticResult SimulateSeriesElasticFreeSwing(const ParameterSet& params,
                                                   const SeriesElasticParams& se,
                                                   const PulseTrain& pulses,
                                                   const SimulationOptions& options);

/// Isometric with the SE: the joint is held at angle_deg, the CE moves.
/// @throws std::invalid_argument as SimulateIsometric and
///   SimulateSeriesElasticFreeSwing.
/// @throws std::runtime_error if the adaptive integrator fails.
SeriesElasticResult SimulateSeriesElasticIsometric(const ParameterSet& params,
                                                   const SeriesElasticParams& se,
                                                   const PulseTrain& pulses, double angle_deg,
                                                   const SimulationOptions& options);

}  // namespace fesbench::model
