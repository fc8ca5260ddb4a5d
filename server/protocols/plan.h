#pragma once

/// @file
/// A protocol's bench steps (docs/PROTOCOLS.md): what BuildPlan makes of a
/// description, resolved parameter values and the subject, and what the
/// engine (runner.h) executes tick by tick at the control rate (1 kHz).
///
/// All durations are whole control ticks (1 ms). Stimulation envelopes are
/// the 200 Hz generators of model/stimulus_generators.h, held between
/// samples as the stimulator's D/A does; set-points come from the
/// trajectories of model/trajectory.h at every tick.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "api/status.h"
#include "model/signal.h"
#include "server/bench/bench.h"
#include "server/protocols/protocol.h"

namespace fesbench::model {
struct JointLimits;
}  // namespace fesbench::model

namespace fesbench::server::protocols {

/// Control ticks per second (docs/ARCHITECTURE.md, units: set-points at 1 kHz).
inline constexpr std::int64_t kTicksPerSecond = 1000;
/// Ticks per 200 Hz sample.
inline constexpr std::int64_t kTicksPerSample = 5;
/// Torque samples averaged as the offset before stimulation (§5.3: "sampled
/// 50 times in rapid succession"), one per tick.
inline constexpr std::int64_t kOffsetSamples = 50;

/// What a step is doing (reported to observers).
using StepPhase = api::StepPhase;
using api::StepPhaseName;

/// One step of a plan.
struct Step {
  StepPhase phase = StepPhase::kRest;
  std::string label;
  std::int64_t ticks = 0;  ///< duration, 1 ms ticks.
  MotorMode motor_mode = MotorMode::kLocked;
  /// Set-points: trajectory(t − step start + trajectory_offset_s) if set,
  /// else a minimum-jerk move from the angle at the step's start to
  /// setpoint_deg when move_from_current, else setpoint_deg held.
  std::shared_ptr<const model::Trajectory> trajectory;
  double trajectory_offset_s = 0.0;
  double setpoint_deg = 90.0;
  bool move_from_current = false;
  /// Stimulation: envelope sample ⌊(tick − step start + stim_offset_ticks)/5⌋,
  /// 0 without an envelope.
  std::shared_ptr<const model::SampledSignal> envelope;
  std::int64_t stim_offset_ticks = 0;
  /// Tolerance test: amplitude ramp_start_ma + ramp_ma_per_s·t instead of an
  /// envelope; the step ends early on StopWithResult.
  bool tolerance_ramp = false;
  double ramp_start_ma = 0.0;
  double ramp_ma_per_s = 0.0;
  /// Ascending search (rapid_parameterisation): the step ends as soon as the
  /// recorded knee angle is at or below this (full extension); the amplitude
  /// then applied becomes the plan's adaptive amplitude (AdaptiveAmplitude).
  std::optional<double> end_below_angle_deg;
  /// Index of the trial the step's samples go to, or −1.
  int trial = -1;
  /// The step is a rest period with this protocol minimum (s); the engine
  /// never runs it shorter.
  double min_rest_s = 0.0;
  /// Tracking (Plan::tracking): the amplitude comes from the controller,
  /// which reads the knee angle at every 200 Hz sample.
  bool closed_loop = false;
};

/// A trial the plan records.
struct TrialPlan {
  std::string name;  ///< e.g. "active_random_binary_rb1".
  MotorMode mode = MotorMode::kLocked;
  bool record_setpoint = false;  ///< motor trials add a setpoint_deg channel.
};

/// The tolerance test's detection settings (docs/PROTOCOLS.md, `tolerance_test`).
struct ToleranceSettings {
  double threshold_torque_nm = 0.5;   ///< torque above the offset taken as response.
  double min_torque_at_max_nm = 6.0;  ///< Appendix F part II.K.3.
};

/// Random-binary amplitude chosen during the run (rapid_parameterisation),
/// applied by scaling the envelopes of `trials` by chosen/planned_ma, within
/// [min_ma, max_ma] (planned_ma if it cannot be found):
///  - target_torque_nm > 0: after `source_trial` (an isometric ramp trial),
///    the amplitude whose isometric torque at the lock angle (IRC by ramp
///    correlation) is target_torque_nm (AmplitudeForTorque);
///  - target_torque_nm = 0: the amplitude at which the ascending search step
///    (Step::end_below_angle_deg) brought the knee to full extension (§5.4.3,
///    "the amplitude that just reaches full extension"), max_ma if it never did.
struct AdaptiveAmplitude {
  int source_trial = 0;
  double target_torque_nm = 6.0;
  double planned_ma = 0.0;  ///< the envelopes' ON amplitude as planned.
  double min_ma = 0.0;      ///< bounds of the chosen amplitude.
  double max_ma = 0.0;
  std::vector<int> trials;
  /// After the search: the trains' top level is at least min_ma +
  /// min_top_fraction·(max_ma − min_ma), so they also visit the levels the
  /// prediction inputs use beyond full extension (0 = the found amplitude).
  double min_top_fraction = 0.0;
};

struct RecordedTrial;
struct RunResult;

/// What a run does with its recorded trials after its last step, before it
/// is done (docs/PROTOCOLS.md, "Adding a protocol"): the protocol's class
/// installs it while building its plan (Plan::analysis), e.g. the rapid
/// routine's identification (rapid_identification.h) and the daily check's
/// comparison (daily_check_protocol.h). A plan without one runs none.
class RunAnalysis {
 public:
  virtual ~RunAnalysis() = default;
  /// The phase the run is in while it analyses: other than kRest, the run
  /// announces a step of this phase (RunObserver::OnStep, labelled by its
  /// name) before it; a run that ends done reports it as its last progress's.
  virtual StepPhase phase() const { return StepPhase::kRest; }
  /// Reads the trials of a run that reached its end (`stops`: the bench's
  /// hard stops) and fills in `result` what it concludes (parameter set,
  /// report, the set's provenance). A non-ok status fails the run with its
  /// message.
  virtual api::Status Analyse(const std::vector<RecordedTrial>& trials,
                              const SubjectContext& subject, const model::JointLimits& stops,
                              RunResult& result) const = 0;
};

/// A tracking run's target, controller and limits (tracking_plan.h; kept
/// out of this header, which must not pull in Eigen: see routes_bench.cc).
struct TrackingSettings;

/// Steps, trials and what follows them.
struct Plan {
  std::string protocol;
  int protocol_version = 1;
  ProtocolKind kind = ProtocolKind::kIsometric;
  ParameterValues parameters;  ///< resolved values.
  std::vector<TrialPlan> trials;
  std::vector<Step> steps;
  /// Stimulation limit of the run, mA (session's max tolerated, or the
  /// tolerance test's ceiling).
  double max_stim_ma = 0.0;
  std::optional<ToleranceSettings> tolerance;
  std::optional<AdaptiveAmplitude> adaptive_amplitude;
  std::shared_ptr<const TrackingSettings> tracking;
  /// What the run does after its last step, or null (none).
  std::shared_ptr<const RunAnalysis> analysis;

  std::int64_t total_ticks() const;
  double duration_s() const { return static_cast<double>(total_ticks()) / kTicksPerSecond; }
};

/// Builds the plan of protocol with resolved values (ResolveParameters) for
/// subject. kInvalidArgument if a generator refuses the values (the message
/// names the parameter), kNotFound for an unknown protocol.
/// `uploaded_target`: tracking's uploaded trajectory at 200 Hz (target 3).
/// `given`: the values the client gave, before defaults (null: every value
/// counts as given); tracking fits its default target to the leg where
/// lo_deg was left out (docs/PROTOCOLS.md, tracking).
api::Result<Plan> BuildPlan(const ProtocolDescription& protocol, const ParameterValues& values,
                            const SubjectContext& subject,
                            const std::vector<double>& uploaded_target = {},
                            const ParameterValues* given = nullptr);

/// ResolveParameters then BuildPlan.
api::Result<Plan> MakePlan(std::string_view protocol, const ParameterValues& values,
                           const SubjectContext& subject,
                           const std::vector<double>& uploaded_target = {});

/// The stimulation envelope (stim_ma at 200 Hz, t = 0 at the trial's first
/// sample) a plan's trial commands, concatenated over its steps. Empty
/// tolerance ramps are not included.
model::SampledSignal TrialEnvelope(const Plan& plan, int trial);

}  // namespace fesbench::server::protocols
