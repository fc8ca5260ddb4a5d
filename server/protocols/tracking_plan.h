#pragma once

/// @file
/// The settings of a `tracking` run (docs/PROTOCOLS.md; plan.h's Plan::tracking).

#include <optional>
#include <string>

#include "model/tracking.h"
#include "server/protocols/plan.h"

namespace fesbench::server::protocols {

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
  double max_rate_ma_per_s = 1000.0;  ///< slew limit of the amplitude.
  /// The run ends (failed) when the controller stays saturated this long.
  double max_saturation_s = 3.0;
};

}  // namespace fesbench::server::protocols
