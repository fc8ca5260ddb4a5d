#pragma once

/// @file
/// The settings of a `tracking` run (docs/PROTOCOLS.md; plan.h's Plan::tracking).

#include <optional>
#include <string>

#include "model/tracking.h"
#include "server/protocols/plan.h"

namespace fesbench::server::protocols {

/// The slew limit of pid without a set, which has no loop to derive one
/// from (docs/PROTOCOLS.md, tracking), mA/s.
inline constexpr double kModelFreeSlewLimitMaPerS = 1000.0;

/// The default target's extended end (lo_deg when the client leaves it out)
/// lies no further extended than the set predicts the knee is held at with
/// this fraction of the activation the maximum amplitude recruits
/// (model::ReachableExtensionDeg), rounded up to a whole degree: the rest
/// of the muscle is the loop's authority for its corrections and the set's
/// error (docs/PROTOCOLS.md, tracking).
inline constexpr double kDefaultTargetActivationFraction = 0.8;
/// The gate of the model-based controllers refuses a target whose most
/// extended angle lies more than this beyond the set's reachable extension
/// at the maximum (TrackingSettings::reachable_extension_deg), deg: the
/// reach is static and scanned in 0.1° steps, a clinician types whole
/// degrees.
inline constexpr double kReachToleranceDeg = 1.0;
/// A fitted default target keeps at least this span below hi_deg, deg.
inline constexpr double kMinFittedSpanDeg = 10.0;

/// A tracking run (ProtocolKind::kTracking): the target and the controller
/// the closed-loop step follows it with (model/tracking.h), and the limits
/// the engine holds the controller to, below it.
struct TrackingSettings {
  /// The leg's set the controller inverts (pid: tunes its gains from); none
  /// for pid with its gains given (docs/PROTOCOLS.md, tracking).
  std::optional<model::ParameterSet> params;
  std::string target_name;     ///< "sine", "holds", "ramp".
  model::KneeTarget target;    ///< from the end of the lead-in on.
  /// The lead-in: a raised-cosine move from the angle measured when the
  /// step starts to the target's first angle, this long.
  double lead_in_s = 3.0;
  model::TrackingOptions options;
  /// Slew limit of the amplitude, mA/s: the run's max_rate_ma_per_s, or
  /// with it 0 model::DefaultSlewLimit of the set (without a set
  /// kModelFreeSlewLimitMaPerS).
  double max_rate_ma_per_s = kModelFreeSlewLimitMaPerS;
  /// With a set: the most extended angle the set predicts the maximum
  /// amplitude holds the knee at (model::ReachableExtensionDeg), reported
  /// with the run's figures.
  std::optional<double> reachable_extension_deg;
  /// The run ends (failed) when the controller stays saturated this long.
  double max_saturation_s = 3.0;
};

}  // namespace fesbench::server::protocols
