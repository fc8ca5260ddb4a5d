#pragma once

/// @file
/// The protocol engine (docs/PROTOCOLS.md; docs/SAFETY.md): runs a Plan on a SafeBench — never
/// on a Bench directly — tick by tick at the control rate (1 kHz):
/// stimulation amplitude and motor set-points through the interlocks, then
/// AdvanceTo the next tick; sensors read at 200 Hz into the trial being
/// recorded (t_s, stim_ma, angle_deg, torque_nm, accel_m_s2, and
/// setpoint_deg for motor trials; EMG at 1 kHz in the trial's emg group),
/// torque offset-corrected by the 50-sample offset measured before each
/// stimulation segment (§5.3).
///
/// Stimulation (docs/MODEL.md, pulse timing): `stim_ma` is the plan's amplitude after the
/// interlock's clamp (what was commanded); the stimulator's pulse clock is
/// restarted at the run's and at each trial's start, so a trial's pulses fall
/// on k / f_pulse from its t_s = 0; a run of the envelope too short to hold a
/// grid time goes out as one TriggerPulse at its start (the rule of
/// model::PulsesFromEnvelope). What the stimulator delivered, read back
/// (SafeBench::DrainDeliveredPulses), is stored with the trial: every pulse
/// in `Trial::pulses` (trial time, delivered mA) and the same as the channel
/// `stim_delivered_ma` (model::StimulusColumn).
///
/// Cancel, Stop and the safety conditions are checked at every tick: a
/// cancel, an e-stop (SafeBench::EStop from any thread) or a fired heartbeat
/// watchdog abort the run within one control period, leaving stimulation at
/// 0. The run's states are those of run_state.h.

#include <atomic>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "api/run.h"
#include "api/status.h"
#include "api/trial.h"
#include "model/identify_common.h"
#include "model/parameter_set.h"
#include "server/protocols/plan.h"
#include "server/protocols/run_transitions.h"
#include "server/safety/safe_bench.h"

namespace fesbench::server::protocols {

/// Thread-safe append-only record of safety events; give `sink()` to the
/// SafeBench so runs can report the events of their span.
class SafetyEventLog {
 public:
  SafeBench::EventSink sink();
  void Append(const SafetyEvent& event);
  std::size_t size() const;
  /// Events from index `from` on.
  std::vector<SafetyEvent> Since(std::size_t from) const;

 private:
  mutable std::mutex mu_;
  std::vector<SafetyEvent> events_;
};

/// A trial as recorded, with what the engine knows about it.
struct RecordedTrial {
  api::Trial trial;                ///< name = plan's trial name; t_s from 0.
  double bench_start_s = 0.0;      ///< bench time of its first sample.
  std::vector<double> offsets_nm;  ///< torque offsets measured (raw N·m), in order.
  bool complete = true;            ///< false if the run ended inside it.
};

/// The tolerance test's outcome (Appendix F part II.K; api/run.h).
using ToleranceResult = api::ToleranceResult;

/// What a run produced.
struct RunResult {
  RunState state = RunState::kQueued;
  std::string reason;  ///< why failed or aborted; empty when done.
  std::string protocol;
  int protocol_version = 1;
  ParameterValues parameters;
  std::vector<RecordedTrial> trials;
  std::optional<model::ParameterSet> parameter_set;  ///< rapid_parameterisation.
  /// The trials (plan indices, ascending) the set was fitted to, when the
  /// analysis says (rapid_parameterisation); empty: every trial of the run.
  std::vector<int> parameter_set_trials;
  /// The set's active (random-binary) trial, a plan index, when it has one.
  std::optional<int> parameter_set_active_trial;
  std::optional<ToleranceResult> tolerance;          ///< tolerance_test.
  /// daily_check: its report (daily_check.h); parameter_set holds a re-fit.
  std::optional<nlohmann::json> daily_check;
  std::vector<SafetyEvent> safety_events;
  /// Figures decided during the run, e.g. "rb_amplitude_ma".
  std::map<std::string, double> values;
  double bench_duration_s = 0.0;
  double wall_duration_s = 0.0;
};

/// A block of recorded samples for live streaming (SSE, DDS; api/run.h).
using SampleBatch = api::SampleBatch;

/// Progress of a run: bench-time fraction and an ETA in wall seconds (api/run.h).
using Progress = api::Progress;

/// Receives a run's events on the run's thread. Default: ignore.
class RunObserver {
 public:
  virtual ~RunObserver() = default;
  virtual void OnStateChanged(RunState /*state*/, const std::string& /*reason*/) {}
  virtual void OnStep(std::size_t /*index*/, const Step& /*step*/) {}
  virtual void OnProgress(const Progress& /*progress*/) {}
  virtual void OnSamples(const SampleBatch& /*batch*/) {}
  virtual void OnTrial(const RecordedTrial& /*trial*/) {}
  virtual void OnFinished(const RunResult& /*result*/) {}
};

struct RunnerOptions {
  /// Bench seconds per wall second the bench is paced at (0 = as fast as
  /// possible); for the ETA only.
  double time_scale = 0.0;
  double progress_interval_s = 0.1;  ///< bench seconds between OnProgress.
  std::size_t batch_samples = 40;    ///< samples per OnSamples batch.
  bool arm_watchdog = true;          ///< arm SafeBench's heartbeat watchdog.
  double heartbeat_timeout_s = 1.0;
  api::Clock* clock = api::Clock::Real();  ///< for wall durations; must outlive the runner.
};

class RunExecution;

/// The engine. Each object runs one plan (a second Run returns failed
/// without touching the bench; BenchOwner makes one per run and enforces one
/// run per bench). Cancel and Stop may be called from any thread, also
/// before Run starts (the run then aborts at once).
class ProtocolRunner {
 public:
  /// @param bench must outlive the runner. @param log may be null.
  ProtocolRunner(SafeBench& bench, SafetyEventLog* log, RunObserver* observer,
                 RunnerOptions options = {});

  /// Runs plan for subject to its end (blocking). Configures the bench's
  /// safety limits (stimulation ≤ plan.max_stim_ma, set-points inside the
  /// subject's range of motion), arms the watchdog, runs the steps, and for
  /// rapid_parameterisation identifies the parameter set.
  RunResult Run(const Plan& plan, const SubjectContext& subject);

  /// Aborts the run at the next tick (state aborted with reason).
  void Cancel(const std::string& reason = "cancelled by client");
  /// "Stop with result": ends the tolerance test's ramp at the current
  /// amplitude, which becomes the max tolerated; other protocols: Cancel.
  void Stop();

  RunState state() const { return state_.load(); }

 private:
  friend class RunExecution;  // one Run's state and parts (run_execution.h)
  bool Transition(RunTransition transition, const std::string& reason);

  SafeBench& bench_;
  SafetyEventLog* log_;
  RunObserver* observer_;
  RunnerOptions options_;
  std::atomic<RunState> state_{RunState::kQueued};
  std::atomic<bool> cancel_{false};
  std::atomic<bool> stop_{false};
  std::mutex reason_mu_;
  std::string cancel_reason_;
  RunResult* result_ = nullptr;
};

/// After the ascending search step (Step::end_below_angle_deg) of a plan with
/// an AdaptiveAmplitude: the amplitude at which the knee reached full
/// extension (`reached_ma`, or max_ma if it never did), clamped to
/// [min_ma, max_ma], becomes values["rb_amplitude_ma"]
/// (values["full_extension_reached"] 1 or 0); every non-zero envelope value u
/// of the adaptive trials then runs as min_ma + (u − min_ma)·scale with
/// scale = (chosen − min_ma)/(planned_ma − min_ma) (stim_floor[trial] =
/// min_ma, stim_scale[trial] = scale), so levels planned between threshold
/// and planned_ma keep their place between threshold and the chosen amplitude.
void ApplySearchedAmplitude(const Plan& plan, std::optional<double> reached_ma,
                            std::map<std::string, double>& values, std::vector<double>& stim_scale,
                            std::vector<double>& stim_floor);

/// The amplitude (mA, in [min_ma, max_ma], 0.1 mA steps) whose isometric
/// torque τ_scale·R(u) from an IRC identified by ramp correlation on
/// `ramp_trial` first reaches target_torque_nm (max_ma if never);
/// kFailedPrecondition if the IRC cannot be identified.
api::Result<double> AmplitudeForTorque(const api::Trial& ramp_trial, double target_torque_nm,
                                       double min_ma, double max_ma);

}  // namespace fesbench::server::protocols
