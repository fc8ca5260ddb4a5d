#pragma once

/// @file
/// Identification from stored trials (docs/MODEL.md; thesis ch. 4, §5.3–5.4,
/// §7.4.1). Loads a session's trials (or explicit trial ids), recognises each
/// by the name the protocol runner gives it (server/protocols/plan.cc), runs
/// conditioning and the thesis's methods, and stores the new parameter-set
/// version(s) with provenance and an audit entry in one transaction.
///
/// Trials by name (the protocol that records them):
///  - isometric_ramp_irc, isometric_step_irc, isometric_impulse_irc: IRC by
///    the chosen method (§4.1) and the contraction pole from the averaged
///    impulse responses of the ramp and impulse trials (Eqs. 4.2, 4.4);
///  - passive_positions + passive_velocities: sequential passive (§4.2.1);
///  - passive_simultaneous_*: simultaneous least squares (Eq. 4.31);
///  - free_swing_passive: free swing (Eq. 4.35) with τ_pta from the
///    positions trial's holds or from a stored parameter set;
///  - active_random_binary_*: active log least squares (Eq. 4.40) and the
///    simplified variants (§5.5.1, §7.3, §7.4.4);
///  - rapid_isometric_ramp_irc, rapid_free_swing_passive,
///    rapid_active_random_binary: method "rapid" (§7.4.1).
/// Conditioning (§5.1): velocity and acceleration of a trial without
/// velocity_deg_s / accel_deg_s2 columns come from its angle by the GCV
/// smoothing spline; f_stim from the identified IRC and dynamics driven by
/// the recorded stim_ma envelope's pulses. Torque is used as recorded (the
/// runner removes the offset; the isometric methods remove it per event).
///
/// Thread-safe (no mutable state besides the database).

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "api/analysis_requests.h"
#include "api/analysis_results.h"
#include "api/status.h"
#include "model/identify_common.h"
#include "model/simulate.h"
#include "server/services/actor.h"
#include "storage/database.h"

namespace fesbench::server::services {

struct IdentificationConfig {
  double pulse_rate_hz = 33.0;  ///< stimulator pulse rate of the recorded trials, Hz.
  /// The bench's stops (method rapid: samples in contact are left out of the
  /// fits and the output-error simulations stop there, as in the run).
  std::optional<model::JointLimits> joint_limits;
};

/// The request's wire form (api/analysis_requests.h).
using IdentificationBreakpoints = api::IdentificationBreakpoints;
using IdentificationRequest = api::IdentificationRequest;

/// One stored version.
/// The result's wire form (api/analysis_results.h).
using StoredFit = api::StoredFit;
using IdentificationResult = api::IdentificationResult;

class IdentificationService {
 public:
  /// `db` must outlive the service.
  explicit IdentificationService(storage::Database& db, IdentificationConfig config = {});

  /// Validates the request (kInvalidArgument naming the field), loads the
  /// trials (kNotFound for an unknown session or trial), checks the needed
  /// kinds are there (kFailedPrecondition naming what is missing), fits, and
  /// stores. A fit that fails on the data is kFailedPrecondition naming it.
  /// Analysts and admins only (kPermissionDenied).
  api::Result<IdentificationResult> Fit(const Actor& actor, const IdentificationRequest& request);

 private:
  storage::Database& db_;
  IdentificationConfig config_;
};

/// Checks the request's values together (no database; the names were parsed
/// by api::IdentificationRequestFromJson): kInvalidArgument naming the field
/// ("session_id", "trial_ids[2]", "contraction_order", "models[1]", …).
api::Status ValidateIdentificationRequest(const IdentificationRequest& request);

}  // namespace fesbench::server::services
