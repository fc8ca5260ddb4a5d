#include "server/protocols/runner.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <limits>
#include <numeric>

#include "model/identify_isometric.h"
#include "model/simulate.h"
#include "server/protocols/daily_check.h"
#include "server/protocols/rapid_identification.h"
#include "server/protocols/tracking_loop.h"

namespace fesbench::server::protocols {
namespace {

double SteadyNow() {
  using namespace std::chrono;
  return duration<double>(steady_clock::now().time_since_epoch()).count();
}

double MinJerk(double u) {
  u = std::clamp(u, 0.0, 1.0);
  return u * u * u * (10.0 - 15.0 * u + 6.0 * u * u);
}

// The trial being recorded.
struct Recorder {
  RecordedTrial rec;
  std::vector<double> t_s, stim_ma, angle_deg, torque_nm, accel_m_s2, setpoint_deg;
  std::vector<double> emg_mv;
  api::PulseRecord pulses;  // read back from the stimulator, trial time
  bool record_setpoint = false;
  // Tracking: the target and the controller's signals, per sample.
  bool closed_loop = false;
  std::vector<double> target_deg, feedforward_ma, correction_ma, tau_scale_nm;
  std::int64_t start_tick = 0;
  double offset_nm = 0.0;
  std::size_t batch_begin = 0;
};

}  // namespace

void ApplySearchedAmplitude(const Plan& plan, std::optional<double> reached_ma,
                            std::map<std::string, double>& values, std::vector<double>& stim_scale,
                            std::vector<double>& stim_floor) {
  if (!plan.adaptive_amplitude) return;
  const AdaptiveAmplitude& adapt = *plan.adaptive_amplitude;
  if (!(adapt.planned_ma > adapt.min_ma)) return;
  // §5.4.3: the amplitude that just reaches full extension; the max
  // tolerated (the search's end) when the knee never got there.
  const double chosen = std::clamp(reached_ma.value_or(adapt.max_ma), adapt.min_ma, adapt.max_ma);
  values["full_extension_amplitude_ma"] = chosen;
  values["full_extension_reached"] = reached_ma ? 1.0 : 0.0;
  const double top = std::max(chosen, adapt.min_ma + std::clamp(adapt.min_top_fraction, 0.0, 1.0) *
                                                         (adapt.max_ma - adapt.min_ma));
  values["rb_amplitude_ma"] = top;
  for (int t : adapt.trials) {
    if (t < 0 || static_cast<std::size_t>(t) >= stim_scale.size()) continue;
    // Levels above threshold keep their place between threshold and the
    // top level: u → min + (u − min)·(top − min)/(planned − min).
    stim_floor[static_cast<std::size_t>(t)] = adapt.min_ma;
    stim_scale[static_cast<std::size_t>(t)] =
        (top - adapt.min_ma) / (adapt.planned_ma - adapt.min_ma);
  }
}

// --- SafetyEventLog -----------------------------------------------------------

SafeBench::EventSink SafetyEventLog::sink() {
  return [this](const SafetyEvent& e) { Append(e); };
}

void SafetyEventLog::Append(const SafetyEvent& event) {
  std::lock_guard lock(mu_);
  events_.push_back(event);
}

std::size_t SafetyEventLog::size() const {
  std::lock_guard lock(mu_);
  return events_.size();
}

std::vector<SafetyEvent> SafetyEventLog::Since(std::size_t from) const {
  std::lock_guard lock(mu_);
  if (from >= events_.size()) return {};
  return {events_.begin() + static_cast<std::ptrdiff_t>(from), events_.end()};
}

// --- ProtocolRunner -------------------------------------------------------------

ProtocolRunner::ProtocolRunner(SafeBench& bench, SafetyEventLog* log, RunObserver* observer,
                               RunnerOptions options)
    : bench_(bench), log_(log), observer_(observer), options_(std::move(options)) {
  if (!options_.wall_clock) options_.wall_clock = SteadyNow;
}

void ProtocolRunner::Cancel(const std::string& reason) {
  {
    std::lock_guard lock(reason_mu_);
    if (cancel_reason_.empty()) cancel_reason_ = reason;
  }
  cancel_.store(true);
}

void ProtocolRunner::Stop() { stop_.store(true); }

bool ProtocolRunner::Transition(RunTransition transition, const std::string& reason) {
  const std::optional<RunState> next = NextState(state_.load(), transition);
  if (!next) return false;
  state_.store(*next);
  if (result_ != nullptr) {
    result_->state = *next;
    if (IsFinal(*next) && *next != RunState::kDone) result_->reason = reason;
  }
  if (observer_ != nullptr) observer_->OnStateChanged(*next, reason);
  return true;
}

RunResult ProtocolRunner::Run(const Plan& plan, const SubjectContext& subject) {
  if (state_.load() != RunState::kQueued) {
    RunResult used;
    used.state = RunState::kFailed;
    used.reason = "a ProtocolRunner runs one plan; this one has run already";
    used.protocol = plan.protocol;
    return used;
  }
  RunResult result;
  result_ = &result;
  result.protocol = plan.protocol;
  result.protocol_version = plan.protocol_version;
  result.parameters = plan.parameters;
  const std::size_t first_event = log_ != nullptr ? log_->size() : 0;
  const double wall0 = options_.wall_clock();

  const auto finish = [&]() -> RunResult {
    bench_.SetStimAmplitude(0.0);
    bench_.DisarmWatchdog();
    if (log_ != nullptr) result.safety_events = log_->Since(first_event);
    result.wall_duration_s = options_.wall_clock() - wall0;
    if (observer_ != nullptr) observer_->OnFinished(result);
    result_ = nullptr;
    return std::move(result);
  };

  if (bench_.estopped()) {
    Transition(RunTransition::kError, "e-stop latched: clear it before starting a run");
    return finish();
  }
  if (api::Status st = ValidateSubject(subject); !st.ok()) {
    Transition(RunTransition::kError, st.ToString());
    return finish();
  }
  const BenchLimits& hw = bench_.bench_limits();
  if (std::max(subject.min_angle_deg, hw.min_angle_deg) >=
      std::min(subject.max_angle_deg, hw.max_angle_deg)) {
    Transition(RunTransition::kError, "the subject's range of motion lies outside the bench's");
    return finish();
  }
  Transition(RunTransition::kStart, "");

  // Interlock limits of this run (DESIGN.md §6): the session's max tolerated
  // amplitude, whatever the plan says. The tolerance test measures it: its
  // ceiling stands alone on a session without a recorded max, or above the
  // recorded max by a clinician's explicit, audited decision.
  SafetyLimits limits;
  const double plan_max_ma =
      std::isfinite(plan.max_stim_ma) ? std::max(plan.max_stim_ma, 0.0) : 0.0;
  const bool ceiling_alone =
      plan.kind == ProtocolKind::kTolerance &&
      (!subject.max_tolerated_recorded || subject.ceiling_above_max.has_value());
  limits.max_stim_ma =
      ceiling_alone ? plan_max_ma : std::min(plan_max_ma, subject.max_tolerated_ma);
  limits.min_angle_deg = subject.min_angle_deg;
  limits.max_angle_deg = subject.max_angle_deg;
  limits.heartbeat_timeout_s = options_.heartbeat_timeout_s;
  bench_.Configure(limits);
  const double max_applied_ma = std::max(0.0, std::min(limits.max_stim_ma, hw.max_stim_ma));
  if (options_.arm_watchdog) bench_.ArmWatchdog();

  const double t0 = bench_.Now_s();
  // DESIGN.md §3: the pulse clock restarts with the run and with each trial
  // and then runs on; pulses read back outside a trial belong to none.
  bench_.RestartPulseClock();
  bench_.DrainDeliveredPulses();
  std::int64_t clock_tick = 0;  // global tick of the last restart
  const std::int64_t total = plan.total_ticks();
  const auto progress_every =
      std::max<std::int64_t>(1, std::llround(options_.progress_interval_s * kTicksPerSecond));
  std::int64_t n = 0;  // global tick

  std::optional<MotorMode> mode;
  double last_setpoint = std::numeric_limits<double>::quiet_NaN();
  double last_stim = -1.0;
  std::optional<Recorder> rec;
  int rec_trial = -1;
  double prev_u = 0.0;                 // the plan's amplitude at the previous tick
  std::int64_t single_pulse_end = -1;  // global tick: a run delivered as one pulse ends here
  std::vector<double> stim_scale(plan.trials.size(), 1.0);
  std::vector<double> stim_floor(plan.trials.size(), 0.0);  // ApplySearchedAmplitude

  // Tracking: the closed-loop step's controller with the limits the engine
  // holds it to, below it (tracking_loop.h).
  std::optional<TrackingLoop> tracking;

  // Tolerance test state.
  ToleranceResult tol;
  std::deque<double> tol_window;
  double tol_sum = 0.0;
  double offset_sd_nm = 0.0;
  if (plan.tolerance) result.tolerance = tol;

  const auto emit_batch = [&](bool all) {
    if (!rec || observer_ == nullptr) return;
    const std::size_t end = rec->t_s.size();
    if (end == rec->batch_begin) return;
    if (!all && end - rec->batch_begin < options_.batch_samples) return;
    SampleBatch b;
    b.trial = rec_trial;
    b.trial_name = plan.trials[static_cast<std::size_t>(rec_trial)].name;
    const auto slice = [&](const std::vector<double>& v) {
      return std::vector<double>(v.begin() + static_cast<std::ptrdiff_t>(rec->batch_begin),
                                 v.end());
    };
    b.t_s = slice(rec->t_s);
    b.stim_ma = slice(rec->stim_ma);
    b.angle_deg = slice(rec->angle_deg);
    b.torque_nm = slice(rec->torque_nm);
    b.accel_m_s2 = slice(rec->accel_m_s2);
    if (rec->closed_loop) {
      b.target_deg = slice(rec->target_deg);
      b.tau_scale_nm = slice(rec->tau_scale_nm);
    }
    rec->batch_begin = end;
    observer_->OnSamples(b);
  };

  const auto collect_pulses = [&] {
    for (const model::Pulse& p : bench_.DrainDeliveredPulses()) {
      if (rec) rec->pulses.Append(p.t_s - rec->rec.bench_start_s, p.stim_ma);
    }
  };

  const auto close_trial = [&](bool complete) {
    if (!rec) return;
    emit_batch(true);
    collect_pulses();
    for (double v : bench_.bench().DrainEmg_mv()) rec->emg_mv.push_back(v);
    api::Trial& t = rec->rec.trial;
    t.name = plan.trials[static_cast<std::size_t>(rec_trial)].name;
    t.sample_rate_hz = 200.0;
    t.SetChannel("t_s", std::move(rec->t_s));
    t.SetChannel("stim_ma", std::move(rec->stim_ma));
    t.SetChannel("angle_deg", std::move(rec->angle_deg));
    t.SetChannel("torque_nm", std::move(rec->torque_nm));
    t.SetChannel("accel_m_s2", std::move(rec->accel_m_s2));
    if (rec->record_setpoint) t.SetChannel("setpoint_deg", std::move(rec->setpoint_deg));
    if (rec->closed_loop) {
      t.SetChannel("target_deg", std::move(rec->target_deg));
      t.SetChannel("feedforward_ma", std::move(rec->feedforward_ma));
      t.SetChannel("correction_ma", std::move(rec->correction_ma));
      t.SetChannel("tau_scale_nm", std::move(rec->tau_scale_nm));
    }
    // What the stimulator delivered, from its read-back (issue 16): the
    // pulses, and the same as an envelope channel (model::StimulusColumn).
    rec->pulses.pulse_rate_hz = hw.pulse_rate_hz;
    rec->pulses.pulse_width_us = hw.pulse_width_us;
    t.SetChannel("stim_delivered_ma",
                 model::StimulusColumn(rec->pulses.Train(), hw.pulse_rate_hz, *t.Values("t_s")));
    t.pulses = std::move(rec->pulses);
    if (!rec->emg_mv.empty()) {
      api::ChannelGroup emg;
      emg.sample_rate_hz = bench_.bench_limits().emg_rate_hz;
      std::vector<double> et(rec->emg_mv.size());
      for (std::size_t i = 0; i < et.size(); ++i)
        et[i] = static_cast<double>(i) / emg.sample_rate_hz;
      emg.Set("t_s", std::move(et));
      emg.Set("emg_mv", std::move(rec->emg_mv));
      t.emg = std::move(emg);
    }
    rec->rec.complete = complete;
    result.trials.push_back(std::move(rec->rec));
    const AdaptiveAmplitude* adapt = plan.adaptive_amplitude ? &*plan.adaptive_amplitude : nullptr;
    if (complete && adapt != nullptr && adapt->source_trial == rec_trial &&
        adapt->planned_ma > 0.0 && adapt->target_torque_nm > 0.0) {
      const api::Result<double> u = AmplitudeForTorque(
          result.trials.back().trial, adapt->target_torque_nm, adapt->min_ma, adapt->max_ma);
      const double chosen = u.ok() ? *u : adapt->planned_ma;
      result.values["rb_amplitude_ma"] = chosen;
      for (int t : adapt->trials)
        stim_scale[static_cast<std::size_t>(t)] = chosen / adapt->planned_ma;
    }
    if (observer_ != nullptr) observer_->OnTrial(result.trials.back());
    rec.reset();
    rec_trial = -1;
  };

  const auto abort_reason = [&]() -> std::optional<std::pair<RunTransition, std::string>> {
    if (bench_.estopped()) {
      const std::string fault = bench_.bench().HardwareFault();
      return std::pair{RunTransition::kEStop, fault.empty() ? std::string("e-stop")
                                                            : "e-stop: " + fault};
    }
    if (bench_.watchdog_fired()) {
      return std::pair{RunTransition::kWatchdog,
                       std::string("watchdog: controlling client stopped heart-beating")};
    }
    if (cancel_.load()) {
      std::lock_guard lock(reason_mu_);
      return std::pair{RunTransition::kCancel, cancel_reason_};
    }
    return std::nullopt;
  };

  std::optional<std::pair<RunTransition, std::string>> aborted;
  for (std::size_t si = 0; si < plan.steps.size() && !aborted; ++si) {
    const Step& step = plan.steps[si];
    if (observer_ != nullptr) observer_->OnStep(si, step);
    if (step.trial != rec_trial) {
      close_trial(true);
      if (step.trial >= 0) {
        rec.emplace();
        rec_trial = step.trial;
        rec->start_tick = n;
        rec->rec.bench_start_s = t0 + static_cast<double>(n) / kTicksPerSecond;
        rec->record_setpoint = plan.trials[static_cast<std::size_t>(step.trial)].record_setpoint;
        bench_.bench().DrainEmg_mv();  // EMG from the trial's first sample on
        bench_.RestartPulseClock();    // the trial's grid: k / f from its t_s = 0
        bench_.DrainDeliveredPulses();
        clock_tick = n;
      }
    }
    // Motor mode first, so a move starts from where the knee is.
    if (!mode || *mode != step.motor_mode) {
      bench_.SetMotorMode(step.motor_mode);
      mode = step.motor_mode;
      if (step.motor_mode != MotorMode::kPosition)
        last_setpoint = std::numeric_limits<double>::quiet_NaN();
    }
    double move_from = step.setpoint_deg;
    if (step.move_from_current) {
      move_from = std::isfinite(last_setpoint) ? last_setpoint : bench_.ReadSensors().angle_deg;
      move_from = std::clamp(move_from, subject.min_angle_deg, subject.max_angle_deg);
    }
    if (step.closed_loop && plan.tracking && !tracking) {
      try {
        tracking.emplace(*plan.tracking, bench_.ReadSensors().angle_deg);
      } catch (const std::invalid_argument& e) {
        aborted = std::pair{RunTransition::kError, std::string("tracking: ") + e.what()};
        break;
      }
      if (rec) rec->closed_loop = true;
    }
    double offset_sum = 0.0, offset_sq = 0.0;
    std::int64_t offset_count = 0;
    std::optional<double> search_reached_ma;  // Step::end_below_angle_deg

    for (std::int64_t k = 0; k < step.ticks; ++k, ++n) {
      if ((aborted = abort_reason())) break;
      if (step.tolerance_ramp && stop_.load()) {
        tol.stopped_by_clinician = true;
        break;
      }
      if (search_reached_ma) break;
      // Set-point (1 kHz) and stimulation (200 Hz envelope, held).
      if (step.motor_mode == MotorMode::kPosition || step.motor_mode == MotorMode::kLocked) {
        double sp = step.setpoint_deg;
        if (step.trajectory) {
          sp = step.trajectory
                   ->At(static_cast<double>(k) / kTicksPerSecond + step.trajectory_offset_s)
                   .angle_deg;
        } else if (step.move_from_current) {
          sp = move_from + (step.setpoint_deg - move_from) *
                               MinJerk(static_cast<double>(k) / static_cast<double>(step.ticks));
        }
        if (sp != last_setpoint) {
          bench_.SetMotorSetpoint(sp);
          last_setpoint = sp;
        }
      }
      double u = 0.0;
      if (step.tolerance_ramp) {
        // Held per 200 Hz sample like every envelope.
        const std::int64_t ks = (k / kTicksPerSample) * kTicksPerSample;
        u = step.ramp_start_ma + step.ramp_ma_per_s * static_cast<double>(ks) / kTicksPerSecond;
      } else if (step.closed_loop && tracking) {
        if (k % kTicksPerSample == 0) {
          if (std::optional<std::string> stop = tracking->Sample(bench_.ReadSensors().angle_deg)) {
            aborted = std::pair{RunTransition::kError, std::move(*stop)};
            break;
          }
        }
        u = tracking->amplitude_ma();
      } else if (step.envelope) {
        const std::int64_t idx = (step.stim_offset_ticks + k) / kTicksPerSample;
        if (idx >= 0 && idx < static_cast<std::int64_t>(step.envelope->values.size())) {
          u = step.envelope->values[static_cast<std::size_t>(idx)];
        }
        if (step.trial >= 0 && u > 0.0) {
          const auto t = static_cast<std::size_t>(step.trial);
          u = stim_floor[t] + (u - stim_floor[t]) * stim_scale[t];
        }
      }
      // A run of the envelope too short to hold a grid time of the pulse
      // clock is one single pulse at its start (model::PulsesFromEnvelope).
      if (step.envelope && u > 0.0 && !(prev_u > 0.0)) {
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
        const double from_s = static_cast<double>(n - clock_tick) / kTicksPerSecond;
        const double to_s = from_s + static_cast<double>(end - k) / kTicksPerSecond;
        if (!model::FirstGridTimeIn(from_s, to_s, hw.pulse_rate_hz)) {
          bench_.TriggerPulse(u);
          single_pulse_end = n + (end - k);
        }
      }
      prev_u = u;
      const double command = n < single_pulse_end ? 0.0 : u;
      if (command != last_stim) {
        bench_.SetStimAmplitude(command);
        last_stim = command;
      }
      if (step.phase == StepPhase::kOffset) {
        const double raw = bench_.ReadSensors().torque_nm;
        offset_sum += raw;
        offset_sq += raw * raw;
        ++offset_count;
      }
      if (rec && (n - rec->start_tick) % kTicksPerSample == 0) {
        const SensorFrame f = bench_.ReadSensors();
        const double applied = bench_.estopped() || bench_.watchdog_fired() ? 0.0
                               : std::isfinite(u) ? std::clamp(u, 0.0, max_applied_ma)
                                                  : 0.0;
        const double torque = f.torque_nm - rec->offset_nm;
        rec->t_s.push_back(static_cast<double>(n - rec->start_tick) / kTicksPerSecond);
        rec->stim_ma.push_back(applied);
        rec->angle_deg.push_back(f.angle_deg);
        rec->torque_nm.push_back(torque);
        rec->accel_m_s2.push_back(f.accel_m_s2);
        if (rec->record_setpoint) rec->setpoint_deg.push_back(last_setpoint);
        if (rec->closed_loop && tracking) {
          const model::TrackingSample& c = tracking->last();
          rec->target_deg.push_back(c.target_deg);
          rec->feedforward_ma.push_back(c.feedforward_ma);
          rec->correction_ma.push_back(c.correction_ma);
          rec->tau_scale_nm.push_back(c.tau_scale_nm);
        }
        for (double v : bench_.bench().DrainEmg_mv()) rec->emg_mv.push_back(v);
        collect_pulses();
        emit_batch(false);
        if (step.end_below_angle_deg && f.angle_deg <= *step.end_below_angle_deg) {
          search_reached_ma = applied;
        }
        if (step.tolerance_ramp) {
          // Threshold: first amplitude whose 50 ms mean torque leaves the
          // offset's noise band (Appendix F part II.K).
          tol_window.push_back(torque);
          tol_sum += torque;
          if (tol_window.size() > 10) {
            tol_sum -= tol_window.front();
            tol_window.pop_front();
          }
          const double mean = tol_sum / static_cast<double>(tol_window.size());
          tol.max_torque_nm = std::max(tol.max_torque_nm, mean);
          if (!tol.threshold_ma && tol_window.size() == 10 && mean > tol.noise_band_nm) {
            tol.threshold_ma = applied;
          }
          tol.max_tolerated_ma = applied;
        }
      }
      bench_.AdvanceTo(t0 + static_cast<double>(n + 1) / kTicksPerSecond);
      if (observer_ != nullptr && (n + 1) % progress_every == 0) {
        Progress p;
        p.bench_elapsed_s = static_cast<double>(n + 1) / kTicksPerSecond;
        p.bench_total_s = static_cast<double>(total) / kTicksPerSecond;
        p.fraction = std::min(1.0, static_cast<double>(n + 1) / static_cast<double>(total));
        const double left = p.bench_total_s - p.bench_elapsed_s;
        const double wall_rate = (options_.wall_clock() - wall0) / p.bench_elapsed_s;
        p.eta_s = options_.time_scale > 0.0 ? left / options_.time_scale : left * wall_rate;
        p.step = si;
        p.phase = step.phase;
        observer_->OnProgress(p);
      }
    }
    if (step.phase == StepPhase::kOffset && offset_count > 0 && rec) {
      rec->offset_nm = offset_sum / static_cast<double>(offset_count);
      rec->rec.offsets_nm.push_back(rec->offset_nm);
      const double var =
          offset_sq / static_cast<double>(offset_count) - rec->offset_nm * rec->offset_nm;
      offset_sd_nm = std::sqrt(std::max(0.0, var));
      if (plan.tolerance) {
        tol.noise_band_nm = std::max(plan.tolerance->threshold_torque_nm, 4.0 * offset_sd_nm);
      }
    }
    if (step.tolerance_ramp && stop_.load()) tol.stopped_by_clinician = true;
    if (step.end_below_angle_deg && !aborted) {
      ApplySearchedAmplitude(plan, search_reached_ma, result.values, stim_scale, stim_floor);
    }
  }

  // An e-stop, watchdog or cancel during the very last tick still counts.
  if (!aborted) aborted = abort_reason();
  // Stop stimulation whatever happened; a cancelled motor holds where it is.
  bench_.SetStimAmplitude(0.0);
  close_trial(!aborted);
  result.bench_duration_s = bench_.Now_s() - t0;
  if (plan.tolerance) {
    if (tol.max_torque_nm < plan.tolerance->min_torque_at_max_nm) {
      tol.warnings.push_back("torque at max below the 6 N·m of Appendix F part II.K.3");
    }
    if (!tol.threshold_ma) tol.warnings.push_back("no torque response above the noise band");
    result.tolerance = tol;
  }
  if (tracking && !result.trials.empty()) tracking->Summarise(result.trials.back().trial, result.values);
  if (aborted) {
    if (aborted->first == RunTransition::kCancel && mode == MotorMode::kPosition &&
        std::isfinite(last_setpoint)) {
      bench_.SetMotorSetpoint(last_setpoint);
    }
    Transition(aborted->first, aborted->second);
    return finish();
  }
  if (plan.rapid) {
    if (observer_ != nullptr) {
      Step identify;
      identify.phase = StepPhase::kIdentify;
      identify.label = "identify";
      observer_->OnStep(plan.steps.size(), identify);
    }
    api::Result<model::ParameterSet> params =
        IdentifyRapidTrials(result.trials, *plan.rapid, subject,
                            model::JointLimits{hw.min_angle_deg, hw.max_angle_deg});
    if (!params.ok()) {
      Transition(RunTransition::kError, "identification failed: " + params.status().message());
      return finish();
    }
    result.parameter_set = std::move(params).value();
  }
  if (plan.daily_check) {
    api::Result<DailyCheckOutcome> check =
        EvaluateDailyCheck(*plan.daily_check, result.trials, subject,
                           model::JointLimits{hw.min_angle_deg, hw.max_angle_deg});
    if (!check.ok()) {
      Transition(RunTransition::kError, check.status().message());
      return finish();
    }
    result.daily_check = std::move(check->report);
    if (check->updated) result.parameter_set = std::move(check->updated);
  }
  if (observer_ != nullptr) {
    Progress p;
    p.fraction = 1.0;
    p.bench_elapsed_s = p.bench_total_s = static_cast<double>(total) / kTicksPerSecond;
    p.step = plan.steps.size();
    p.phase = plan.rapid ? StepPhase::kIdentify : StepPhase::kRest;
    observer_->OnProgress(p);
  }
  Transition(RunTransition::kComplete, "");
  return finish();
}

api::Result<double> AmplitudeForTorque(const api::Trial& ramp_trial, double target_torque_nm,
                                       double min_ma, double max_ma) {
  try {
    const model::IrcResult irc =
        model::IdentifyIrc(model::IrcMethod::kRampCorrelation, api::ToTrialColumns(ramp_trial));
    for (double u = min_ma; u <= max_ma; u += 0.1) {
      if (irc.torque_scale_nm * irc.irc(u) >= target_torque_nm) return u;
    }
    return max_ma;
  } catch (const std::exception& e) {
    return api::Status::FailedPrecondition(std::string("IRC of the ramp trial: ") + e.what());
  }
}

}  // namespace fesbench::server::protocols
