#pragma once

/// @file
/// The engine's side of a tracking run (docs/SAFETY.md, "Closed-loop stimulation"): the controller
/// of model/tracking.h held to the limits the engine keeps below it — the slew
/// limit and the saturation stop (SafeBench clamps the maximum) — and the
/// run's figures afterwards. Used by the runner at every 200 Hz sample of
/// the closed-loop step.

#include <map>
#include <optional>
#include <string>

#include "api/status.h"
#include "api/trial.h"
#include "model/tracking.h"
#include "server/protocols/tracking_plan.h"

namespace fesbench::server::protocols {

class TrackingLoop {
 public:
  /// Builds the controller for `settings`' target after a lead-in from
  /// `start_angle_deg`, the knee's angle when the step starts. Without a
  /// set, pid with its gains given runs as the amplitude PID alone (it uses
  /// no model; docs/PROTOCOLS.md, tracking). `settings` must outlive the
  /// loop. kInvalidArgument with the model's message for what
  /// model::WithLeadIn or model::TrackingController refuses, and for a
  /// model-based controller or pid without gains when there is no set.
  static api::Result<TrackingLoop> Create(const TrackingSettings& settings, double start_angle_deg);

  /// One 200 Hz sample: the controller's decision for the knee angle
  /// measured now, slew-limited. Returns the reason the run must end when
  /// the measured angle is not finite, when the controller has stayed
  /// saturated longer than max_saturation_s, or when the knee still
  /// oscillates after the controller halved its gains
  /// model::kMaxOscillationBackoffs times (docs/SAFETY.md, "Closed-loop
  /// stimulation").
  std::optional<std::string> Sample(double measured_deg);

  /// The amplitude to apply until the next sample, mA.
  double amplitude_ma() const { return amplitude_ma_; }
  /// The controller's last decision (target, feedforward, correction, τ̂).
  const model::TrackingSample& last() const { return last_; }
  double saturated_s() const { return saturated_total_s_; }

  /// The run's figures (PROTOCOLS.md, tracking): tracking_rms_deg,
  /// tracking_max_error_deg, overshoot_deg and settling_s (holds: median
  /// and worst) and the error's RMS above 1 Hz over the target after the
  /// lead-in, the seconds it commanded 0 mA and the maximum there,
  /// charge_uc from the delivered pulses, saturated_s, the final
  /// tau_scale_nm, the gains it started with, the oscillation back-offs
  /// taken and, with a set, reachable_extension_deg
  /// (TrackingSettings::reachable_extension_deg).
  void Summarise(const api::Trial& trial, std::map<std::string, double>& values) const;

 private:
  explicit TrackingLoop(const TrackingSettings& settings) : settings_(settings) {}

  // pid without a set: the threshold plus the amplitude PID, as
  // model::TrackingController's pid does (model/tracking.h).
  model::TrackingSample UpdateModelFreePid(double measured_deg);

  const TrackingSettings& settings_;
  std::optional<model::TrackingController> controller_;    // with a set
  model::KneeTarget target_;                               // without: the lead-in and target
  std::optional<model::Pid> pid_;                          // without: pid's gains
  std::optional<model::OscillationDetector> oscillation_;  // without: its back-off
  int backoffs_ = 0;
  std::size_t index_ = 0;  // samples taken
  model::TrackingSample last_;
  double amplitude_ma_ = 0.0;
  int saturated_samples_ = 0;
  double saturated_total_s_ = 0.0;
  double zero_s_ = 0.0;    // commanded 0 mA, after the lead-in
  double at_max_s_ = 0.0;  // commanded the maximum, after the lead-in
};

}  // namespace fesbench::server::protocols
