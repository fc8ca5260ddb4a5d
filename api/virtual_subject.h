#pragma once

/// @file
/// The virtual subject behind the simulated bench (docs/ARCHITECTURE.md, "The
/// benches") as it travels: GET and PUT /bench/virtual-subject (admin), read
/// by the study (clients/cli/study) and written by the server. A truth
/// parameter set of the identification model (docs/MODEL.md) plus the
/// "fidelity" effects the identification model leaves out (thesis §3.3,
/// §6.4, §6.6), the subject's anthropometrics and stimulation levels. The
/// bench's behaviour and the seeded generators are server/bench/virtual_subject.h.
///
/// ```json
/// {"name": "virtual-7", "seed": 7,
///  "truth": {<parameter set, docs/MODEL.md>},
///  "threshold_ma": 18.2, "max_tolerated_ma": 41.0,
///  "anthropometrics": {"body_mass_kg": 70, "height_m": 1.75, "shank_length_m": 0.43,
///                      "accel_distance_m": 0.28, "thigh_elevation_deg": 9},
///  "fidelity": {"twitch_variation": 0.3, "series_stiffness_nm_per_deg": 35, ...}}
/// ```
/// `truth`, `threshold_ma` and `max_tolerated_ma` are required; `name`,
/// `seed`, `anthropometrics`, `fidelity` and each field inside the last two
/// are optional and default to the values below. Unknown keys are rejected
/// (the form is also the PUT body, where a typo would otherwise silently keep
/// a default).

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

#include "api/status.h"
#include "model/parameter_set.h"

namespace fesbench::api {

/// Effects of the real leg and bench beyond the identification model.
/// Magnitudes are ≥ 0; 0 turns an effect off.
struct Fidelity {
  /// Twitch shape variation with level (Fig. 3-8, §3.3): a fraction
  /// `twitch_variation · R(u)` of each pulse drives a contraction chain of
  /// the other order (2 ↔ 3) whose pole puts its peak at the same time, so
  /// the shape changes with level while the peak stays (0–1).
  double twitch_variation = 0.3;
  /// Series elastic element stiffness K_se (Eqs. 3.11–3.14, §6.4), N·m/deg;
  /// 0 = infinitely stiff (off). The CE–SE interaction through f_atv delays
  /// the twitch peak (Fig. 6-13).
  double series_stiffness_nm_per_deg = 35.0;
  /// Passive torque–angle hysteresis (Fig. 3-7, §6.6): half-width of the
  /// loop, N·m, reached after `hysteresis_angle_deg` of travel.
  double hysteresis_nm = 0.5;
  double hysteresis_angle_deg = 3.0;
  /// Static (Coulomb) friction in the joint (Fig. 6-22), N·m, regularised as
  /// F·tanh(θ̇ / friction_velocity_deg_s).
  double static_friction_nm = 0.3;
  double friction_velocity_deg_s = 0.5;
  /// Fatigue (§3.3): dF/dt = rate·f_stim·(1 − F) − F/recovery_s; force × (1 − F).
  double fatigue_rate_per_s = 0.02;
  double fatigue_recovery_s = 30.0;
  /// Post-tetanic potentiation (§3.3): dP/dt = rate·f_stim·(max − P) − P/decay_s;
  /// activation f → (1 + P)·f / (1 + P·f): twitches grow by up to 1 + max,
  /// fused tetanus (f = 1) is unchanged.
  double potentiation_max = 0.3;
  double potentiation_rate_per_s = 0.5;
  double potentiation_decay_s = 60.0;
  /// Potentiometer non-linearity as a fraction of one turn (120° of knee,
  /// §5.1): error = k·120°·sin(2π·θ/120°).
  double pot_nonlinearity = 0.01;
  /// White sensor noise, one standard deviation per channel.
  double angle_noise_deg = 0.02;
  double torque_noise_nm = 0.05;
  double accel_noise_m_s2 = 0.05;
  double emg_noise_mv = 0.005;
  /// 12-bit quantisation of the angle and accelerometer channels (§5.1). The
  /// torque channel is always quantised at 0.0381 N·m/LSB, ±78 N·m.
  bool quantise_adc = true;
  /// M-wave on the EMG after each pulse, peak mV at R(u) = 1.
  double emg_m_wave_mv = 0.5;
  /// Voluntary co-contraction bursts (§5.2.1): mean rate per minute (0 = off),
  /// net extensor torque and EMG RMS during a burst (0.5–1.5 s each).
  double cocontraction_per_min = 0.0;
  double cocontraction_torque_nm = 2.0;
  double cocontraction_emg_mv = 0.2;

  /// Every effect off, no noise, no angle/accel quantisation.
  static Fidelity Off();
  /// The defaults above (a realistic bench).
  static Fidelity Default() { return {}; }
  friend bool operator==(const Fidelity&, const Fidelity&) = default;
};

/// Body measures (docs/ARCHITECTURE.md, storage) and bench placement (§5.1).
struct Anthropometrics {
  double body_mass_kg = 70.0;
  double height_m = 1.75;
  double shank_length_m = 0.43;    ///< knee centre to lateral malleolus.
  double accel_distance_m = 0.28;  ///< accelerometer from the knee centre (≈ 11 in, §5.1).
  /// Thigh elevation above horizontal as the subject reclines (Fig. 5-5):
  /// the shank hangs vertically at θ = 90° − elevation (81° for 9°).
  double thigh_elevation_deg = 9.0;
  friend bool operator==(const Anthropometrics&, const Anthropometrics&) = default;
};

/// A virtual subject: what the simulated bench's leg is made of.
struct VirtualSubject {
  std::string name = "virtual";
  /// Seed of the subject's own random effects (sensor noise, voluntary
  /// bursts). The bench combines it with its own seed.
  std::uint64_t seed = 1;
  model::ParameterSet truth;       ///< the docs/MODEL.md model part.
  double threshold_ma = 20.0;      ///< lowest amplitude giving torque.
  double max_tolerated_ma = 45.0;  ///< highest amplitude the subject accepts.
  Anthropometrics anthropometrics;
  Fidelity fidelity;
  friend bool operator==(const VirtualSubject&, const VirtualSubject&) = default;
};

/// Every field, including defaults. Never fails.
nlohmann::json VirtualSubjectToJson(const VirtualSubject& subject);
nlohmann::json FidelityToJson(const Fidelity& fidelity);

/// Parses and validates. kInvalidArgument with the dotted field path on:
/// a missing or wrongly typed field; an unknown key; a bad truth parameter
/// set (api::ParameterSetFromJson's message, path prefixed "truth.");
/// threshold_ma < 0; max_tolerated_ma ≤ threshold_ma or > 100; a non-finite
/// number; a negative fidelity magnitude; twitch_variation > 1;
/// hysteresis_angle_deg, friction_velocity_deg_s, fatigue_recovery_s or
/// potentiation_decay_s ≤ 0; anthropometric lengths or mass ≤ 0;
/// accel_distance_m > 1; thigh_elevation_deg outside [−45, 45].
Result<VirtualSubject> VirtualSubjectFromJson(const nlohmann::json& json);

/// Validates a subject built in code with the same rules (the truth with
/// model::JointModel and model::ValidateContraction).
Status ValidateVirtualSubject(const VirtualSubject& subject);

}  // namespace fesbench::api
