#include "server/protocols/trial_recorder.h"

#include <algorithm>
#include <chrono>
#include <utility>

#include "model/simulate.h"

namespace fesbench::server::protocols {

void TrialRecorder::Open(int index, std::string name, std::int64_t start_tick,
                         double bench_start_s, bool record_setpoint) {
  Reset();
  index_ = index;
  name_ = std::move(name);
  start_tick_ = start_tick;
  recorded_.bench_start_s = bench_start_s;
  record_setpoint_ = record_setpoint;
  bench_.DrainEmg_mv();          // EMG from the trial's first sample on
  bench_.RestartPulseClock();    // the trial's grid: k / f from its t_s = 0
  bench_.DrainDeliveredPulses();
  bench_.DrainDeviceCommands();
  // The trial's start on both clocks: UTC for people, monotonic for the
  // device commands' times (and any other host's log of the same run).
  start_steady_ = std::chrono::steady_clock::now();
  recorded_.trial.start_time_unix_ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(
          std::chrono::system_clock::now().time_since_epoch())
          .count();
}

void TrialRecorder::SetOffset(double offset_nm) {
  offset_nm_ = offset_nm;
  recorded_.offsets_nm.push_back(offset_nm);
}

void TrialRecorder::Append(double t_s, double stim_ma, double angle_deg, double torque_nm,
                           double accel_m_s2, double setpoint_deg,
                           const model::TrackingSample* tracking) {
  t_s_.push_back(t_s);
  stim_ma_.push_back(stim_ma);
  angle_deg_.push_back(angle_deg);
  torque_nm_.push_back(torque_nm);
  accel_m_s2_.push_back(accel_m_s2);
  if (record_setpoint_) setpoint_deg_.push_back(setpoint_deg);
  if (closed_loop_ && tracking != nullptr) {
    target_deg_.push_back(tracking->target_deg);
    feedforward_ma_.push_back(tracking->feedforward_ma);
    correction_ma_.push_back(tracking->correction_ma);
    tau_scale_nm_.push_back(tracking->tau_scale_nm);
  }
  for (double v : bench_.DrainEmg_mv()) emg_mv_.push_back(v);
  CollectPulses();
  EmitBatch(false);
}

void TrialRecorder::EmitBatch(bool all) {
  if (observer_ == nullptr) return;
  const std::size_t end = t_s_.size();
  if (end == batch_begin_) return;
  if (!all && end - batch_begin_ < batch_samples_) return;
  SampleBatch b;
  b.trial = index_;
  b.trial_name = name_;
  const auto slice = [&](const std::vector<double>& v) {
    return std::vector<double>(v.begin() + static_cast<std::ptrdiff_t>(batch_begin_), v.end());
  };
  b.t_s = slice(t_s_);
  b.stim_ma = slice(stim_ma_);
  b.angle_deg = slice(angle_deg_);
  b.torque_nm = slice(torque_nm_);
  b.accel_m_s2 = slice(accel_m_s2_);
  if (closed_loop_) {
    b.target_deg = slice(target_deg_);
    b.tau_scale_nm = slice(tau_scale_nm_);
  }
  batch_begin_ = end;
  observer_->OnSamples(b);
}

void TrialRecorder::CollectPulses() {
  for (const model::Pulse& p : bench_.DrainDeliveredPulses()) {
    pulses_.Append(p.t_s - recorded_.bench_start_s, p.stim_ma);
  }
}

RecordedTrial TrialRecorder::Close(bool complete) {
  EmitBatch(true);
  CollectPulses();
  for (double v : bench_.DrainEmg_mv()) emg_mv_.push_back(v);
  const BenchLimits& hw = bench_.bench_limits();
  api::Trial& t = recorded_.trial;
  t.name = name_;
  t.sample_rate_hz = hw.sample_rate_hz;
  t.SetChannel("t_s", std::move(t_s_));
  t.SetChannel("stim_ma", std::move(stim_ma_));
  t.SetChannel("angle_deg", std::move(angle_deg_));
  t.SetChannel("torque_nm", std::move(torque_nm_));
  t.SetChannel("accel_m_s2", std::move(accel_m_s2_));
  if (record_setpoint_) t.SetChannel("setpoint_deg", std::move(setpoint_deg_));
  if (closed_loop_) {
    t.SetChannel("target_deg", std::move(target_deg_));
    t.SetChannel("feedforward_ma", std::move(feedforward_ma_));
    t.SetChannel("correction_ma", std::move(correction_ma_));
    t.SetChannel("tau_scale_nm", std::move(tau_scale_nm_));
  }
  // What the stimulator delivered, from its read-back (docs/SAFETY.md, "Stimulator read-back"): the
  // pulses, and the same as an envelope channel (model::StimulusColumn).
  pulses_.pulse_rate_hz = hw.pulse_rate_hz;
  pulses_.pulse_width_us = hw.pulse_width_us;
  t.SetChannel("stim_delivered_ma",
               model::StimulusColumn(pulses_.Train(), hw.pulse_rate_hz, *t.Values("t_s")));
  t.pulses = std::move(pulses_);
  if (const auto device = bench_.HardwareStimulator()) {
    // What the device was told, and when (api::DeviceCommandLog).
    api::DeviceCommandLog log;
    log.device = device->device;
    log.pulse_rate_hz = device->pulse_rate_hz;
    log.current_step_ma = device->current_step_ma;
    log.start_monotonic_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                 start_steady_.time_since_epoch())
                                 .count();
    for (const Bench::DeviceCommand& c : bench_.DrainDeviceCommands()) {
      log.t_s.push_back(std::max(
          0.0, std::chrono::duration<double>(c.written - start_steady_).count()));
      log.requested_ma.push_back(c.requested_ma);
      log.commanded_ma.push_back(std::min(c.commanded_ma, c.requested_ma));
      log.single_pulse.push_back(c.single_pulse);
    }
    t.device_commands = std::move(log);
  }
  if (!emg_mv_.empty()) {
    api::ChannelGroup emg;
    emg.sample_rate_hz = hw.emg_rate_hz;
    std::vector<double> et(emg_mv_.size());
    for (std::size_t i = 0; i < et.size(); ++i) et[i] = static_cast<double>(i) / emg.sample_rate_hz;
    emg.Set("t_s", std::move(et));
    emg.Set("emg_mv", std::move(emg_mv_));
    t.emg = std::move(emg);
  }
  recorded_.complete = complete;
  RecordedTrial out = std::move(recorded_);
  Reset();
  return out;
}

void TrialRecorder::Reset() {
  index_ = -1;
  name_.clear();
  start_tick_ = 0;
  recorded_ = RecordedTrial{};
  for (auto* v : {&t_s_, &stim_ma_, &angle_deg_, &torque_nm_, &accel_m_s2_, &setpoint_deg_,
                  &emg_mv_, &target_deg_, &feedforward_ma_, &correction_ma_, &tau_scale_nm_}) {
    v->clear();
  }
  pulses_ = api::PulseRecord{};
  record_setpoint_ = false;
  closed_loop_ = false;
  offset_nm_ = 0.0;
  batch_begin_ = 0;
}

}  // namespace fesbench::server::protocols
