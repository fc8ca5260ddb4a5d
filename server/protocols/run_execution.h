#pragma once

/// @file
/// One execution of a Plan by a ProtocolRunner (internal to protocols/): the
/// state of the run between its ticks and the parts of ProtocolRunner::Run,
/// each a member — checks before the start, the interlock limits, a step's
/// entry, its ticks (set-point, amplitude, recording), its end (offsets,
/// tolerance, amplitude search), and the conclusion (the plan's analysis,
/// Plan::analysis). The recording is a TrialRecorder, the tolerance test's
/// measurement a ToleranceDetector, tracking a TrackingLoop.

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "server/protocols/runner.h"
#include "server/protocols/tolerance_detector.h"
#include "server/protocols/tracking_loop.h"
#include "server/protocols/trial_recorder.h"

namespace fesbench::server::protocols {

class RunExecution {
 public:
  RunExecution(ProtocolRunner& runner, const Plan& plan, const SubjectContext& subject);
  /// Runs the plan to its end (ProtocolRunner::Run).
  RunResult Execute();

 private:
  using Abort = std::pair<RunTransition, std::string>;

  /// Refusals before anything moves: e-stop latched, a bad subject, a range
  /// of motion outside the bench's. False with the run failed.
  bool CheckBeforeStart();
  /// The interlock limits of this run (docs/SAFETY.md) and the watchdog.
  void ConfigureSafety();
  /// Opens the step's trial, sets the motor mode, starts tracking. False
  /// when the run must end (aborted_ set).
  bool EnterStep(const Step& step);
  /// The step's ticks; returns with aborted_ set if the run must end.
  void RunTicks(std::size_t index, const Step& step);
  /// The set-point of tick `k` of `step`, sent when it changed.
  void DriveMotor(const Step& step, std::int64_t k);
  /// The plan's amplitude at tick `k` of `step` (before the interlock);
  /// nullopt with aborted_ set when tracking stops the run.
  std::optional<double> PlannedAmplitude(const Step& step, std::int64_t k);
  /// A run of the envelope too short to hold a pulse-clock grid time goes
  /// out as one pulse at its start (model::PulsesFromEnvelope).
  void DeliverShortRunAsOnePulse(const Step& step, std::int64_t k, double u);
  /// A recorded sample at tick n_ (every 200 Hz); feeds the tolerance
  /// detector and the amplitude search.
  void RecordSample(const Step& step, double u);
  void ReportProgress(std::size_t index, const Step& step);
  /// The step's end: its torque offset, the clinician's stop, the searched
  /// amplitude.
  void FinishStep(const Step& step);
  /// Closes the trial being recorded (and adapts the amplitude it decides).
  void CloseTrial(bool complete);
  /// E-stop, watchdog or cancel, as the transition and reason to end with.
  std::optional<Abort> AbortReason();
  /// After the last step: the tolerance outcome, the tracking figures, the
  /// aborted end, or the plan's analysis (Plan::analysis) and done.
  RunResult Conclude();
  /// Stops the bench's outputs and hands the result out.
  RunResult Finish();
  /// The last progress of a run that ended, whichever way: the bench time
  /// it ran as its total (docs/API.md, Runs).
  void ReportFinalProgress();

  ProtocolRunner& runner_;
  SafeBench& bench_;
  const Plan& plan_;
  const SubjectContext& subject_;
  const BenchLimits& hw_;
  // A stimulator that fires its own train on its own clock (not the bench's
  // grid): a short run of the envelope is always its single pulse.
  bool device_paced_train_ = false;
  RunResult result_;
  std::size_t first_event_ = 0;
  double wall0_ = 0.0;
  double t0_ = 0.0;
  double max_applied_ma_ = 0.0;

  std::int64_t n_ = 0;           // run tick
  std::int64_t skipped_ticks_ = 0;  // planned ticks of steps that ended early
  std::int64_t clock_tick_ = 0;  // run tick of the last pulse-clock restart
  std::int64_t progress_every_ = 1;
  Progress last_progress_;  // the last reported, for the final one
  std::optional<MotorMode> mode_;
  double last_setpoint_;
  double last_stim_ = -1.0;
  double move_from_ = 0.0;
  double prev_u_ = 0.0;               // the plan's amplitude at the previous tick
  std::int64_t single_pulse_end_ = -1;  // run tick: a run delivered as one pulse ends here
  std::vector<double> stim_scale_;
  std::vector<double> stim_floor_;  // ApplySearchedAmplitude
  TrialRecorder recorder_;
  std::optional<TrackingLoop> tracking_;
  std::optional<ToleranceDetector> tolerance_;
  // The step's offset window (StepPhase::kOffset) and amplitude search.
  double offset_sum_ = 0.0, offset_sq_ = 0.0;
  std::int64_t offset_count_ = 0;
  std::optional<double> search_reached_ma_;
  bool subject_limit_ = false;  // the subject signalled "no higher" (tolerance ramp)
  std::optional<Abort> aborted_;
};

}  // namespace fesbench::server::protocols
