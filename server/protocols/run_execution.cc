#include "server/protocols/run_execution.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "api/json_fields.h"
#include "model/simulate.h"
#include "server/protocols/protocol.h"

namespace fesbench::server::protocols {
namespace {

double MinJerk(double u) {
  u = std::clamp(u, 0.0, 1.0);
  return u * u * u * (10.0 - 15.0 * u + 6.0 * u * u);
}

double TickSeconds(std::int64_t ticks) { return static_cast<double>(ticks) / kTicksPerSecond; }

}  // namespace

RunExecution::RunExecution(ProtocolRunner& runner, const Plan& plan, const SubjectContext& subject)
    : runner_(runner),
      bench_(runner.bench_),
      plan_(plan),
      subject_(subject),
      hw_(runner.bench_.bench_limits()),
      last_setpoint_(std::numeric_limits<double>::quiet_NaN()),
      stim_scale_(plan.trials.size(), 1.0),
      stim_floor_(plan.trials.size(), 0.0),
      recorder_(runner.bench_, runner.observer_, runner.options_.batch_samples) {
  if (const auto device = bench_.HardwareStimulator()) {
    device_paced_train_ = device->paces_own_train;
  }
  runner_.result_ = &result_;
  result_.protocol = plan.protocol;
  result_.protocol_version = plan.protocol_version;
  result_.parameters = plan.parameters;
  first_event_ = runner_.log_ != nullptr ? runner_.log_->size() : 0;
  wall0_ = runner_.options_.clock->MonotonicSeconds();
  if (plan.tolerance) {
    tolerance_.emplace(*plan.tolerance);
    result_.tolerance = tolerance_->current();
  }
}

RunResult RunExecution::Execute() {
  if (!CheckBeforeStart()) return Finish();
  runner_.Transition(RunTransition::kStart, "");
  ConfigureSafety();
  t0_ = bench_.Now_s();
  // docs/MODEL.md, pulse timing: the pulse clock restarts with the run and with each trial
  // and then runs on; pulses read back outside a trial belong to none.
  bench_.RestartPulseClock();
  bench_.DrainDeliveredPulses();
  progress_every_ = std::max<std::int64_t>(
      1, std::llround(runner_.options_.progress_interval_s * kTicksPerSecond));
  for (std::size_t index = 0; index < plan_.steps.size() && !aborted_; ++index) {
    const Step& step = plan_.steps[index];
    if (runner_.observer_ != nullptr) runner_.observer_->OnStep(index, step);
    if (!EnterStep(step)) break;
    RunTicks(index, step);
    FinishStep(step);
  }
  return Conclude();
}

bool RunExecution::CheckBeforeStart() {
  if (bench_.estopped()) {
    runner_.Transition(RunTransition::kError, "e-stop latched: clear it before starting a run");
    return false;
  }
  if (api::Status st = ValidateSubject(subject_); !st.ok()) {
    runner_.Transition(RunTransition::kError, st.ToString());
    return false;
  }
  if (std::max(subject_.min_angle_deg, hw_.min_angle_deg) >=
      std::min(subject_.max_angle_deg, hw_.max_angle_deg)) {
    runner_.Transition(RunTransition::kError,
                       "the subject's range of motion lies outside the bench's");
    return false;
  }
  return true;
}

void RunExecution::ConfigureSafety() {
  // Interlock limits of this run (docs/SAFETY.md): the session's max tolerated
  // amplitude, whatever the plan says. The tolerance test measures it: its
  // ceiling stands alone on a session without a recorded max, or above the
  // recorded max by a clinician's explicit, audited decision.
  SafetyLimits limits;
  const double plan_max_ma =
      std::isfinite(plan_.max_stim_ma) ? std::max(plan_.max_stim_ma, 0.0) : 0.0;
  const bool reasoned = subject_.ceiling_above_max &&
                        api::CheckPrintableText(*subject_.ceiling_above_max, "ceiling_reason").ok();
  const bool ceiling_alone =
      plan_.kind == ProtocolKind::kTolerance && (!subject_.max_tolerated_recorded || reasoned);
  limits.max_stim_ma =
      ceiling_alone ? plan_max_ma : std::min(plan_max_ma, subject_.max_tolerated_ma);
  limits.min_angle_deg = subject_.min_angle_deg;
  limits.max_angle_deg = subject_.max_angle_deg;
  limits.heartbeat_timeout_s = runner_.options_.heartbeat_timeout_s;
  bench_.Configure(limits);
  max_applied_ma_ = std::max(0.0, std::min(limits.max_stim_ma, hw_.max_stim_ma));
  if (runner_.options_.arm_watchdog) bench_.ArmWatchdog();
}

bool RunExecution::EnterStep(const Step& step) {
  if (step.trial != recorder_.index()) {
    CloseTrial(true);
    if (step.trial >= 0) {
      const TrialPlan& trial = plan_.trials[static_cast<std::size_t>(step.trial)];
      recorder_.Open(step.trial, trial.name, n_, t0_ + TickSeconds(n_), trial.record_setpoint);
      clock_tick_ = n_;
    }
  }
  // Motor mode first, so a move starts from where the knee is.
  if (!mode_ || *mode_ != step.motor_mode) {
    bench_.SetMotorMode(step.motor_mode);
    mode_ = step.motor_mode;
    if (step.motor_mode != MotorMode::kPosition) {
      last_setpoint_ = std::numeric_limits<double>::quiet_NaN();
    }
  }
  move_from_ = step.setpoint_deg;
  if (step.move_from_current) {
    move_from_ = std::isfinite(last_setpoint_) ? last_setpoint_ : bench_.ReadSensors().angle_deg;
    move_from_ = std::clamp(move_from_, subject_.min_angle_deg, subject_.max_angle_deg);
  }
  if (step.closed_loop && plan_.tracking && !tracking_) {
    api::Result<TrackingLoop> loop =
        TrackingLoop::Create(*plan_.tracking, bench_.ReadSensors().angle_deg);
    if (!loop.ok()) {
      aborted_ = Abort{RunTransition::kError, "tracking: " + loop.status().message()};
      return false;
    }
    tracking_.emplace(std::move(loop).value());
    if (recorder_.open()) recorder_.MarkClosedLoop();
  }
  offset_sum_ = offset_sq_ = 0.0;
  offset_count_ = 0;
  search_reached_ma_.reset();
  return true;
}

void RunExecution::RunTicks(std::size_t index, const Step& step) {
  std::int64_t k = 0;
  for (; k < step.ticks; ++k, ++n_) {
    if ((aborted_ = AbortReason())) break;
    if (step.tolerance_ramp && runner_.stop_.load()) {
      if (tolerance_) tolerance_->MarkStoppedByClinician();
      break;
    }
    if (step.tolerance_ramp && subject_limit_) break;
    if (search_reached_ma_) break;
    DriveMotor(step, k);
    const std::optional<double> planned = PlannedAmplitude(step, k);
    if (!planned) break;
    const double u = *planned;
    DeliverShortRunAsOnePulse(step, k, u);
    prev_u_ = u;
    const double command = n_ < single_pulse_end_ ? 0.0 : u;
    if (command != last_stim_) {
      bench_.SetStimAmplitude(command);
      last_stim_ = command;
    }
    if (step.phase == StepPhase::kOffset) {
      const double raw = bench_.ReadSensors().torque_nm;
      offset_sum_ += raw;
      offset_sq_ += raw * raw;
      ++offset_count_;
    }
    if (recorder_.open() && (n_ - recorder_.start_tick()) % kTicksPerSample == 0) {
      RecordSample(step, u);
    }
    bench_.AdvanceTo(t0_ + TickSeconds(n_ + 1));
    ReportProgress(index, step);
  }
  // A step ended early (the clinician's stop, the subject's limit, a search
  // that reached its angle): the bench time left shrinks by what it skipped.
  skipped_ticks_ += step.ticks - k;
}

void RunExecution::DriveMotor(const Step& step, std::int64_t k) {
  // Set-point at the control rate (1 kHz).
  if (step.motor_mode != MotorMode::kPosition && step.motor_mode != MotorMode::kLocked) return;
  double setpoint = step.setpoint_deg;
  if (step.trajectory) {
    setpoint = step.trajectory->At(TickSeconds(k) + step.trajectory_offset_s).angle_deg;
  } else if (step.move_from_current) {
    setpoint = move_from_ + (step.setpoint_deg - move_from_) *
                                MinJerk(static_cast<double>(k) / static_cast<double>(step.ticks));
  }
  if (setpoint != last_setpoint_) {
    bench_.SetMotorSetpoint(setpoint);
    last_setpoint_ = setpoint;
  }
}

std::optional<double> RunExecution::PlannedAmplitude(const Step& step, std::int64_t k) {
  // Stimulation: the 200 Hz envelope, held between its samples.
  if (step.tolerance_ramp) {
    const std::int64_t held = (k / kTicksPerSample) * kTicksPerSample;
    return step.ramp_start_ma + step.ramp_ma_per_s * TickSeconds(held);
  }
  if (step.closed_loop && tracking_) {
    if (k % kTicksPerSample == 0) {
      if (std::optional<std::string> stop = tracking_->Sample(bench_.ReadSensors().angle_deg)) {
        aborted_ = Abort{RunTransition::kError, std::move(*stop)};
        return std::nullopt;
      }
    }
    return tracking_->amplitude_ma();
  }
  if (!step.envelope) return 0.0;
  double u = 0.0;
  const std::int64_t idx = (step.stim_offset_ticks + k) / kTicksPerSample;
  if (idx >= 0 && idx < static_cast<std::int64_t>(step.envelope->values.size())) {
    u = step.envelope->values[static_cast<std::size_t>(idx)];
  }
  if (step.trial >= 0 && u > 0.0) {
    const auto t = static_cast<std::size_t>(step.trial);
    u = stim_floor_[t] + (u - stim_floor_[t]) * stim_scale_[t];
  }
  return u;
}

void RunExecution::DeliverShortRunAsOnePulse(const Step& step, std::int64_t k, double u) {
  if (!step.envelope || !(u > 0.0) || prev_u_ > 0.0) return;
  // The run in the envelope (a trial's steps share it, one step per run).
  std::int64_t end = k + 1;
  for (;;) {
    const std::int64_t idx = (step.stim_offset_ticks + end) / kTicksPerSample;
    if (idx < 0 || idx >= static_cast<std::int64_t>(step.envelope->values.size()) ||
        !(step.envelope->values[static_cast<std::size_t>(idx)] > 0.0)) {
      break;
    }
    ++end;
  }
  const double from_s = TickSeconds(n_ - clock_tick_);
  const double to_s = from_s + TickSeconds(end - k);
  // On the bench's grid a run holding a grid time gets that grid pulse. A
  // device pacing its own train is not in step with the bench: an amplitude
  // held shorter than its period may fire no pulse at all, so such a run is
  // its single pulse.
  const bool shorter_than_a_period = (to_s - from_s) * hw_.pulse_rate_hz < 1.0;
  if (device_paced_train_ ? shorter_than_a_period
                          : !model::FirstGridTimeIn(from_s, to_s, hw_.pulse_rate_hz)) {
    bench_.TriggerPulse(u);
    single_pulse_end_ = n_ + (end - k);
  }
}

void RunExecution::RecordSample(const Step& step, double u) {
  const SensorFrame f = bench_.ReadSensors();
  const double applied = bench_.estopped() || bench_.watchdog_fired() ? 0.0
                         : std::isfinite(u) ? std::clamp(u, 0.0, max_applied_ma_)
                                            : 0.0;
  const double torque = f.torque_nm - recorder_.offset_nm();
  recorder_.Append(TickSeconds(n_ - recorder_.start_tick()), applied, f.angle_deg, torque,
                   f.accel_m_s2, last_setpoint_,
                   recorder_.closed_loop() && tracking_ ? &tracking_->last() : nullptr);
  if (step.end_below_angle_deg && f.angle_deg <= *step.end_below_angle_deg) {
    search_reached_ma_ = applied;
  }
  if (step.tolerance_ramp && tolerance_) {
    tolerance_->Sample(torque, applied);
    subject_limit_ = subject_limit_ || f.subject_limit;
  }
}

void RunExecution::ReportProgress(std::size_t index, const Step& step) {
  RunObserver* observer = runner_.observer_;
  if (observer == nullptr || (n_ + 1) % progress_every_ != 0) return;
  const std::int64_t total = std::max<std::int64_t>(plan_.total_ticks() - skipped_ticks_, n_ + 1);
  Progress p;
  p.bench_elapsed_s = TickSeconds(n_ + 1);
  p.bench_total_s = TickSeconds(total);
  p.bench_planned_s = TickSeconds(plan_.total_ticks());
  p.fraction = std::min(1.0, static_cast<double>(n_ + 1) / static_cast<double>(total));
  const double left = p.bench_total_s - p.bench_elapsed_s;
  const double wall_rate = (runner_.options_.clock->MonotonicSeconds() - wall0_) / p.bench_elapsed_s;
  p.eta_s = runner_.options_.time_scale > 0.0 ? left / runner_.options_.time_scale
                                              : left * wall_rate;
  p.step = index;
  p.phase = step.phase;
  last_progress_ = p;
  observer->OnProgress(p);
}

void RunExecution::FinishStep(const Step& step) {
  if (step.phase == StepPhase::kOffset && offset_count_ > 0 && recorder_.open()) {
    const double count = static_cast<double>(offset_count_);
    const double mean = offset_sum_ / count;
    recorder_.SetOffset(mean);
    const double variance = offset_sq_ / count - mean * mean;
    if (tolerance_) tolerance_->SetOffsetNoise(std::sqrt(std::max(0.0, variance)));
  }
  if (step.tolerance_ramp && runner_.stop_.load() && !subject_limit_ && tolerance_) {
    tolerance_->MarkStoppedByClinician();
  }
  if (step.end_below_angle_deg && !aborted_) {
    ApplySearchedAmplitude(plan_, search_reached_ma_, result_.values, stim_scale_, stim_floor_);
  }
}

void RunExecution::CloseTrial(bool complete) {
  if (!recorder_.open()) return;
  const int index = recorder_.index();
  result_.trials.push_back(recorder_.Close(complete));
  const AdaptiveAmplitude* adapt = plan_.adaptive_amplitude ? &*plan_.adaptive_amplitude : nullptr;
  if (complete && adapt != nullptr && adapt->source_trial == index && adapt->planned_ma > 0.0 &&
      adapt->target_torque_nm > 0.0) {
    const api::Result<double> u = AmplitudeForTorque(
        result_.trials.back().trial, adapt->target_torque_nm, adapt->min_ma, adapt->max_ma);
    const double chosen = u.ok() ? *u : adapt->planned_ma;
    result_.values["rb_amplitude_ma"] = chosen;
    for (int t : adapt->trials) stim_scale_[static_cast<std::size_t>(t)] = chosen / adapt->planned_ma;
  }
  if (runner_.observer_ != nullptr) runner_.observer_->OnTrial(result_.trials.back());
}

std::optional<RunExecution::Abort> RunExecution::AbortReason() {
  if (bench_.estopped()) {
    const api::Status fault = bench_.HardwareFault();
    return Abort{RunTransition::kEStop,
                 fault.ok() ? std::string("e-stop") : "e-stop: " + fault.message()};
  }
  if (bench_.watchdog_fired()) {
    return Abort{RunTransition::kWatchdog,
                 std::string("watchdog: controlling client stopped heart-beating")};
  }
  if (runner_.cancel_.load()) {
    std::lock_guard lock(runner_.reason_mu_);
    return Abort{RunTransition::kCancel, runner_.cancel_reason_};
  }
  return std::nullopt;
}

RunResult RunExecution::Conclude() {
  // An e-stop, watchdog or cancel during the very last tick still counts.
  if (!aborted_) aborted_ = AbortReason();
  // Stop stimulation whatever happened; a cancelled motor holds where it is.
  bench_.SetStimAmplitude(0.0);
  CloseTrial(!aborted_);
  result_.bench_duration_s = bench_.Now_s() - t0_;
  if (tolerance_) {
    result_.tolerance = tolerance_->Finish();
    // 1: the ramp ended where the subject signalled the limit (not the
    // clinician's stop, not the ceiling).
    result_.values["subject_signalled_limit"] =
        subject_limit_ && !result_.tolerance->stopped_by_clinician ? 1.0 : 0.0;
  }
  if (tracking_ && !result_.trials.empty()) {
    tracking_->Summarise(result_.trials.back().trial, result_.values);
  }
  if (aborted_) {
    if (aborted_->first == RunTransition::kCancel && mode_ == MotorMode::kPosition &&
        std::isfinite(last_setpoint_)) {
      bench_.SetMotorSetpoint(last_setpoint_);
    }
    runner_.Transition(aborted_->first, aborted_->second);
    return Finish();
  }
  if (plan_.analysis) {
    const StepPhase phase = plan_.analysis->phase();
    if (runner_.observer_ != nullptr && phase != StepPhase::kRest) {
      Step analysis;
      analysis.phase = phase;
      analysis.label = std::string(StepPhaseName(phase));
      runner_.observer_->OnStep(plan_.steps.size(), analysis);
    }
    const model::JointLimits joint{hw_.min_angle_deg, hw_.max_angle_deg};
    if (api::Status st = plan_.analysis->Analyse(result_.trials, subject_, joint, result_);
        !st.ok()) {
      runner_.Transition(RunTransition::kError, st.message());
      return Finish();
    }
  }
  runner_.Transition(RunTransition::kComplete, "");
  return Finish();
}

void RunExecution::ReportFinalProgress() {
  if (runner_.observer_ == nullptr) return;
  Progress p = last_progress_;
  const std::int64_t planned = plan_.total_ticks();
  // The time run, not the plan's, however the run ended; the fraction stays
  // that of the plan's bench time (1 when done).
  p.bench_elapsed_s = p.bench_total_s = TickSeconds(n_);
  p.bench_planned_s = TickSeconds(planned);
  p.eta_s = 0.0;
  if (result_.state == RunState::kDone) {
    p.fraction = 1.0;
    p.step = plan_.steps.size();
    p.phase = plan_.analysis ? plan_.analysis->phase() : StepPhase::kRest;
  } else {
    p.fraction = planned > 0 ? std::min(1.0, static_cast<double>(n_) / static_cast<double>(planned))
                             : 0.0;
  }
  runner_.observer_->OnProgress(p);
}

RunResult RunExecution::Finish() {
  bench_.SetStimAmplitude(0.0);
  bench_.DisarmWatchdog();
  ReportFinalProgress();
  if (runner_.log_ != nullptr) result_.safety_events = runner_.log_->Since(first_event_);
  result_.wall_duration_s = runner_.options_.clock->MonotonicSeconds() - wall0_;
  if (runner_.observer_ != nullptr) runner_.observer_->OnFinished(result_);
  runner_.result_ = nullptr;
  return std::move(result_);
}

}  // namespace fesbench::server::protocols
