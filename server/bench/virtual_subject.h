#pragma once

/// @file
/// The virtual subject behind the simulated bench (docs/ARCHITECTURE.md): a truth
/// parameter set of the identification model (docs/MODEL.md) plus the
/// "fidelity" effects the identification model leaves out (thesis §3.3,
/// §6.4, §6.6), the subject's anthropometrics and stimulation levels.
///
/// Every fidelity effect has an on/off switch or a magnitude whose zero turns
/// it off; with `Fidelity::Off()` the virtual leg is exactly the model of
/// docs/MODEL.md (the anchor test against model/simulate.h).

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "api/virtual_subject.h"
#include "model/parameter_set.h"

namespace fesbench::server {

/// The virtual subject's data and its JSON (api/virtual_subject.h).
using Fidelity = api::Fidelity;
using Anthropometrics = api::Anthropometrics;
using VirtualSubject = api::VirtualSubject;
using api::FidelityToJson;
using api::ValidateVirtualSubject;
using api::VirtualSubjectFromJson;
using api::VirtualSubjectToJson;

/// The vertical-shank angle, 90° − thigh elevation, deg.
double HangingAngleDeg(const Anthropometrics& anthropometrics);

/// Ranges of the seeded generator (thesis §5.2.1, §6.5, Table 6.3–6.4,
/// docs/ARCHITECTURE.md, "The benches").
struct SubjectRanges {
  double min_inertia_kgm2 = 0.17, max_inertia_kgm2 = 0.70;
  double min_max_tolerated_ma = 30.0, max_max_tolerated_ma = 60.0;
  double min_max_torque_nm = 10.0, max_max_torque_nm = 60.0;
  double nominal_pole_per_s = 25.0, pole_spread = 0.1;  ///< pole = 25·(1 ± 0.1).
  double min_zeta = 0.02, max_zeta = 0.15;
};

/// Draws a plausible subject (full model, 3rd-order contraction) from the
/// seed: anthropometrics → J (Winter's shank-and-foot segment) and gravity;
/// tissue stiffness near the ends of the range; passive damping set so the
/// linearised free-swing ζ (model::LinearisePassive about
/// model::PassiveRestAngle, Table 6.4) is in range; IRC from threshold to saturation;
/// Gaussian f_ata, Hill-like f_atv; τ_scale from the drawn max isometric
/// torque. Same seed → identical subject. Fidelity is Fidelity::Default().
VirtualSubject DrawVirtualSubject(std::uint64_t seed, const SubjectRanges& ranges = {});

/// Shape families of drawn subjects. kThesis is DrawVirtualSubject's
/// generator (the default); kAnalytic (DrawAnalyticSubject) samples other
/// analytic shapes, so a study is not tuned to one generator; kPlateau
/// (DrawPlateauSubject) shapes neither draws: a recruitment plateau below
/// full activation, steep end-range stiffness, strong potentiation and slow
/// fatigue recovery.
enum class SubjectFamily { kThesis, kAnalytic, kPlateau };

/// "thesis" / "analytic" / "plateau".
std::string_view SubjectFamilyName(SubjectFamily family);
/// The family named `name`, or nullopt for an unknown name.
std::optional<SubjectFamily> SubjectFamilyFromName(std::string_view name);

/// Draws a subject of the analytic family from the seed (an independent
/// random stream: seed N here is unrelated to DrawVirtualSubject(N)):
/// - anthropometrics: height 1.55–1.93 m, body-mass index 19–29 kg/m²;
///   J = (Eq. 4.13 + brace)·(0.9–1.1), redrawn until inside the ranges (so
///   the anthropometrics and J agree; for ranges no such body reaches in
///   1000 draws, J is clamped into them, as DrawVirtualSubject does);
/// - τ_pta(θ) = m·g·l·sin(θ − θ_hang) + k1·e^{k2(θ−θ_hi)} − k3·e^{−k4(θ−θ_lo)}
///   (gravity plus exponential end-range stiffness, Eq. 7.3 of §7.4.4 with an
///   extension-end term), θ_hi 100–115°, θ_lo 5–20°, each end term ≤ 50 N·m
///   at 0° and 120°;
/// - τ_ptv: two lines with different slopes for flexion and extension
///   velocity (ratio 1.3–2.5; "two line segments with a discontinuity at zero",
///   §8.2 item 4), their mean slope giving
///   the drawn free-swing ζ about the rest angle;
/// - 3rd-order contraction, pole 20–30 s⁻¹; IRC
///   (1 − e^{−a·x²})/(1 − e^{−a}), a 2–5, x from threshold to saturation;
/// - f_ata a Gaussian centred at 40–52° or 78–95° (the thesis generator's
///   55–75° excluded), width 20–30° or 46–60° (30–45° excluded) with
///   f_ata(90°) ≥ 0.3 of its peak; f_atv = 1 + A·tanh(v/v0) with its own A, v0
///   for concentric (v < 0: A 0.4–0.85, v0 120–400 deg/s) and eccentric
///   (A 0.2–0.6, v0 60–200 deg/s) velocity;
/// - max isometric torque (at the f_ata peak, max tolerated) 10–60 N·m.
/// Curves are sampled at 41 breakpoints over 0–120° and ±400 deg/s into the
/// piecewise-linear truth (referenced and normalised, §6.5, §6.7).
/// Fidelity is Fidelity::Default().
VirtualSubject DrawAnalyticSubject(std::uint64_t seed, const SubjectRanges& ranges = {});

/// Draws a subject of the plateau family from the seed (an independent
/// random stream: seed N here is unrelated to the other families' seed N):
/// - anthropometrics: height 1.50–1.95 m, body-mass index 18–32 kg/m²;
///   J = (Eq. 4.13 + brace)·(0.9–1.1), redrawn until inside the ranges (or
///   clamped into them, as DrawAnalyticSubject);
/// - τ_pta(θ) = m·g·l·sin(θ − θ_hang) + A_hi·e^{(θ−110°)/w_hi} −
///   A_lo·e^{(10°−θ)/w_lo}: gravity plus steep exponential stiffness at both
///   ends (Eq. 7.3 of §7.4.4 with an extension-end term), A 20–50 N·m at
///   the bench's stops (10°, 110°), w 3–8° (the end torque falls by e
///   every w inside the stop), sampled every 2° over 0–120°;
/// - τ_ptv = b·v·(1 + g·(v/200 deg/s)²), g 0–0.5, b giving the drawn
///   free-swing ζ about the rest angle;
/// - 3rd-order contraction, pole 20–30 s⁻¹;
/// - IRC: zero to threshold (0.3–0.5 of the max tolerated), then
///   p·(1 − (1 − x)^n), n 2–3, to a plateau p = 0.6–0.9 of full activation
///   reached at 0.7–0.9 of the max tolerated and kept above it (an
///   identified IRC, normalised to R = 1 at its top, has τ_scale·p for
///   τ_scale: the same torques);
/// - f_ata a Gaussian centred at 55–85°, width 30–50°; f_atv concentric
///   1 + A·tanh(v/v0) (A 0.5–0.8, v0 150–350 deg/s), eccentric a hyperbola
///   rising to 1.2–1.5 (half-speed 80–200 deg/s);
/// - max isometric torque (at the f_ata peak, max tolerated) 10–60 N·m;
/// - Fidelity::Default() but strong post-tetanic potentiation
///   (potentiation_max 0.6–1.0) and slow fatigue recovery
///   (fatigue_recovery_s 90–180 s), §3.3.
VirtualSubject DrawPlateauSubject(std::uint64_t seed, const SubjectRanges& ranges = {});

/// DrawVirtualSubject, DrawAnalyticSubject or DrawPlateauSubject by family.
VirtualSubject DrawSubject(std::uint64_t seed, SubjectFamily family,
                           const SubjectRanges& ranges = {});

/// Steady isometric torque at stim_ma with the knee locked at angle_deg in
/// the model without fidelity effects (Eqs. 3.18–3.20):
/// τ_scale·f_ata(θ)·f_atv(0)·R(u), N·m (the active part only).
double SteadyIsometricActiveTorqueNm(const model::ParameterSet& truth, double stim_ma,
                                     double angle_deg);

}  // namespace fesbench::server
