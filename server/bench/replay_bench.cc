#include "server/bench/replay_bench.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

namespace fesbench::server {
namespace {

constexpr double kLimitSwitchMarginDeg = 2.0;  // as on the simulated bench

}  // namespace

ReplayBench::ReplayBench(ReplayBenchOptions options)
    : options_(std::move(options)), pacer_(options_.clock, options_.time_scale) {}

api::Result<std::unique_ptr<ReplayBench>> ReplayBench::Create(std::vector<api::Trial> trials,
                                                              ReplayBenchOptions options) {
  if (trials.empty()) return api::Status::InvalidArgument("no trials to replay", "trials");
  std::unique_ptr<ReplayBench> bench(new ReplayBench(std::move(options)));
  double start = 0.0;
  for (std::size_t i = 0; i < trials.size(); ++i) {
    const api::Trial& trial = trials[i];
    if (api::Status st = api::ValidateTrial(trial); !st.ok()) {
      return api::Status::InvalidArgument(
          "trial " + std::to_string(i) + ": " + st.message(),
          "trials[" + std::to_string(i) + "]" + (st.field().empty() ? "" : "." + st.field()));
    }
    const std::vector<double>& t = *trial.Values(api::kTimeChannel);
    const double t0 = t.front();
    Playing p;
    p.start_s = start;
    p.end_s = start + (t.back() - t0) + 1.0 / trial.sample_rate_hz;
    const auto track = [&](std::string_view name, const api::ChannelGroup& group) {
      Track tr;
      const std::vector<double>* v = group.Values(name);
      const std::vector<double>* gt = group.Values(api::kTimeChannel);
      if (v == nullptr || gt == nullptr) return tr;
      tr.values = *v;
      tr.t_s.reserve(gt->size());
      for (double ti : *gt) tr.t_s.push_back(start + (ti - t0));
      return tr;
    };
    const api::ChannelGroup main = trial.MainGroup();
    p.angle = track(bench_channels::kAngle, main);
    p.torque = track(bench_channels::kTorque, main);
    p.accel = track(bench_channels::kAccel, main);
    p.stim = track(bench_channels::kStim, main);
    p.emg = trial.emg ? track(bench_channels::kEmg, *trial.emg) : track(bench_channels::kEmg, main);
    if (trial.pulses) {
      for (const model::Pulse& pulse : trial.pulses->Train()) {
        p.pulses.push_back({start + (pulse.t_s - t0), pulse.stim_ma});
      }
    }
    start = p.end_s;
    bench->trials_.push_back(std::move(p));
  }
  bench->end_s_ = start;
  return bench;
}

api::Result<std::unique_ptr<ReplayBench>> ReplayBench::FromCsvFiles(
    const std::vector<std::filesystem::path>& paths, ReplayBenchOptions options) {
  std::vector<api::Trial> trials;
  for (const auto& path : paths) {
    api::Result<api::Trial> trial = api::ReadTrialCsvFile(path, options.limits.sample_rate_hz);
    if (!trial.ok()) return trial.status();
    trial->name = path.stem().string();
    trials.push_back(std::move(trial).value());
  }
  return Create(std::move(trials), std::move(options));
}

void ReplayBench::Record(ReplayCommand::Kind kind, double value) {
  std::lock_guard lock(mu_);
  commands_.push_back({kind, Now_s(), value});
}

void ReplayBench::SetStimAmplitude(double stim_ma) {
  Record(ReplayCommand::Kind::kStimAmplitude, stim_ma);
}
void ReplayBench::TriggerPulse(double stim_ma) { Record(ReplayCommand::Kind::kTriggerPulse, stim_ma); }
void ReplayBench::RestartPulseClock() { Record(ReplayCommand::Kind::kRestartPulseClock, 0.0); }
void ReplayBench::SetMotorMode(MotorMode mode) {
  Record(ReplayCommand::Kind::kMotorMode, static_cast<double>(mode));
}
void ReplayBench::SetMotorSetpoint(double angle_deg) {
  Record(ReplayCommand::Kind::kMotorSetpoint, angle_deg);
}

void ReplayBench::HardwareEStop() {
  // Never blocks: the flag first; the log entry only if the lock is free.
  estop_.store(true, std::memory_order_release);
  std::unique_lock lock(mu_, std::try_to_lock);
  if (lock.owns_lock()) commands_.push_back({ReplayCommand::Kind::kEStop, Now_s(), 0.0});
}

void ReplayBench::ClearHardwareEStop() {
  estop_.store(false, std::memory_order_release);
  Record(ReplayCommand::Kind::kClearEStop, 0.0);
}

std::vector<ReplayCommand> ReplayBench::Commands() const {
  std::lock_guard lock(mu_);
  return commands_;
}

void ReplayBench::AdvanceTo(double t_s) {
  if (!(t_s > t_)) return;
  constexpr double kStepS = 1e-3;
  if (pacer_.time_scale() > 0.0) {
    // Pace in 1 ms steps like the simulated bench.
    while (t_ < t_s) {
      t_ = std::min(t_s, t_ + kStepS);
      now_s_.store(t_, std::memory_order_release);
      pacer_.Pace(t_);
    }
  }
  t_ = t_s;
  now_s_.store(t_, std::memory_order_release);
}

double ReplayBench::Sample(const Track& track, double t_s) {
  if (track.values.empty()) return 0.0;
  const auto it = std::upper_bound(track.t_s.begin(), track.t_s.end(), t_s + 1e-9);
  if (it == track.t_s.begin()) return track.values.front();
  return track.values[static_cast<std::size_t>(it - track.t_s.begin()) - 1];
}

std::size_t ReplayBench::CurrentTrial() const {
  const double t = Now_s();
  for (std::size_t i = 0; i < trials_.size(); ++i) {
    if (t < trials_[i].end_s) return i;
  }
  return trials_.size() - 1;
}

SensorFrame ReplayBench::ReadSensors() {
  const Playing& p = trials_[CurrentTrial()];
  SensorFrame f;
  f.t_s = t_;
  f.angle_deg = Sample(p.angle, t_);
  f.torque_nm = Sample(p.torque, t_);
  f.accel_m_s2 = Sample(p.accel, t_);
  f.estop = HardwareEStopped();
  f.stim_ma = f.estop ? 0.0 : Sample(p.stim, t_);
  if (!p.angle.values.empty()) {
    f.limit_flexion = f.angle_deg >= options_.limits.max_angle_deg - kLimitSwitchMarginDeg;
    f.limit_extension = f.angle_deg <= options_.limits.min_angle_deg + kLimitSwitchMarginDeg;
  }
  return f;
}

std::vector<double> ReplayBench::DrainEmg_mv() {
  std::vector<double> out;
  for (const Playing& p : trials_) {
    const Track& e = p.emg;
    const auto lo = std::upper_bound(e.t_s.begin(), e.t_s.end(), emg_drained_to_s_ + 1e-9);
    const auto hi = std::upper_bound(e.t_s.begin(), e.t_s.end(), t_ + 1e-9);
    for (auto it = lo; it < hi; ++it) {
      out.push_back(e.values[static_cast<std::size_t>(it - e.t_s.begin())]);
    }
  }
  emg_drained_to_s_ = t_;
  return out;
}

std::vector<model::Pulse> ReplayBench::DrainDeliveredPulses() {
  std::vector<model::Pulse> out;
  const auto before = [](double t, const model::Pulse& p) { return t < p.t_s; };
  for (const Playing& p : trials_) {
    const auto lo = std::upper_bound(p.pulses.begin(), p.pulses.end(),
                                     pulses_drained_to_s_ + 1e-9, before);
    const auto hi = std::upper_bound(p.pulses.begin(), p.pulses.end(), t_ + 1e-9, before);
    if (lo < hi) out.insert(out.end(), lo, hi);
  }
  pulses_drained_to_s_ = t_;
  return out;
}

}  // namespace fesbench::server
