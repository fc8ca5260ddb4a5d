#include "server/safety/safe_bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

namespace fesbench::server {
namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// A delivered amplitude may differ from the commanded one by the output
// stage's resolution; the simulated stimulator delivers exactly.
constexpr double kReadBackToleranceMa = 1e-6;
constexpr std::size_t kMaxReadBackPulses = 100'000;
}  // namespace

SafeBench::SafeBench(Bench& bench, EventSink sink, api::Clock* clock)
    : bench_(bench),
      sink_(std::move(sink)),
      watchdog_(clock != nullptr ? clock : api::Clock::Real()) {
  estop_.store(bench_.HardwareEStopped());
}

void SafeBench::Configure(const SafetyLimits& limits) {
  {
    std::lock_guard lock(mu_);
    limits_ = limits;
    configured_ = true;
  }
  bench_.SetStimulationCeiling(StimCeiling());  // the driver's own second check
}

SafetyLimits SafeBench::limits() const {
  std::lock_guard lock(mu_);
  return limits_;
}

double SafeBench::StimCeiling() const {
  const double bench_max = bench_.limits().max_stim_ma;
  std::lock_guard lock(mu_);
  // A missing or non-finite session maximum means no stimulation at all.
  if (!configured_ || !std::isfinite(limits_.max_stim_ma)) return 0.0;
  return std::clamp(limits_.max_stim_ma, 0.0, std::max(bench_max, 0.0));
}

std::pair<double, double> SafeBench::AngleRange() const {
  const double bench_lo = bench_.limits().min_angle_deg;
  const double bench_hi = bench_.limits().max_angle_deg;
  std::lock_guard lock(mu_);
  // The subject's range, always inside the bench's; a non-finite or empty
  // range shrinks to a point that is still inside the bench's range.
  const double lo = std::isfinite(limits_.min_angle_deg)
                        ? std::clamp(limits_.min_angle_deg, bench_lo, bench_hi)
                        : bench_lo;
  const double hi = std::isfinite(limits_.max_angle_deg)
                        ? std::clamp(limits_.max_angle_deg, bench_lo, bench_hi)
                        : bench_lo;
  return {lo, std::max(lo, hi)};
}

void SafeBench::Emit(SafetyEvent event) const {
  if (sink_) sink_(event);
}

void SafeBench::SetStimAmplitude(double stim_ma) {
  if (estop_.load() || watchdog_.fired()) {
    bench_.SetStimAmplitude(0.0);
    return;
  }
  const double max_ma = StimCeiling();
  double applied = stim_ma;
  if (!std::isfinite(stim_ma) || stim_ma < 0.0) applied = 0.0;
  if (applied > max_ma) applied = max_ma;
  if (applied != stim_ma) {
    Emit({SafetyEvent::Kind::kStimClamped, bench_.Now_s(), stim_ma, applied,
          "stimulation limited to " + std::to_string(max_ma) + " mA"});
  }
  bench_.SetStimAmplitude(applied);
}

void SafeBench::TriggerPulse(double stim_ma) {
  if (estop_.load() || watchdog_.fired()) return;
  const double max_ma = StimCeiling();
  double applied = std::isfinite(stim_ma) ? std::clamp(stim_ma, 0.0, max_ma) : 0.0;
  if (applied != stim_ma) {
    Emit({SafetyEvent::Kind::kStimClamped, bench_.Now_s(), stim_ma, applied,
          "pulse limited to " + std::to_string(max_ma) + " mA"});
  }
  if (applied > 0.0) bench_.TriggerPulse(applied);
}

void SafeBench::SetMotorMode(MotorMode mode) {
  if (estop_.load() || watchdog_.fired()) mode = MotorMode::kDisabled;
  bench_.SetMotorMode(mode);
}

void SafeBench::SetMotorSetpoint(double angle_deg) {
  const auto [lo, hi] = AngleRange();
  if (!std::isfinite(angle_deg)) {
    Emit({SafetyEvent::Kind::kSetpointClamped, bench_.Now_s(), angle_deg, kNaN,
          "non-finite set-point ignored"});
    return;
  }
  const double applied = std::clamp(angle_deg, lo, hi);
  if (applied != angle_deg) {
    Emit({SafetyEvent::Kind::kSetpointClamped, bench_.Now_s(), angle_deg, applied,
          "set-point limited to the range of motion"});
  }
  bench_.SetMotorSetpoint(applied);
}

void SafeBench::MakeSafe() {
  bench_.SetStimAmplitude(0.0);
  bench_.SetMotorMode(MotorMode::kDisabled);
}

void SafeBench::AdvanceTo(double t_s) {
  CheckWatchdog();
  bench_.AdvanceTo(t_s);
  if (!estop_.load()) {
    // A latch the bench set on its own (its device failed): an e-stop.
    if (const api::Status fault = bench_.HardwareFault(); !fault.ok()) EStop(fault.message());
  }
  CheckReadBack();
}

void SafeBench::CheckReadBack() {
  std::vector<model::Pulse> pulses = bench_.DrainDeliveredPulses();
  if (pulses.empty()) return;
  const double max_ma = StimCeiling();
  for (const model::Pulse& p : pulses) {
    // The clamp in SetStimAmplitude / TriggerPulse should make this
    // impossible; if it happens, something below this layer bypassed it.
    if (!(p.stim_ma <= max_ma + kReadBackToleranceMa)) {
      EStop("stimulator read-back: a " + std::to_string(p.stim_ma) + " mA pulse at " +
            std::to_string(p.t_s) + " s exceeds the " + std::to_string(max_ma) + " mA limit");
      break;
    }
  }
  std::lock_guard lock(readback_mu_);
  if (readback_.size() + pulses.size() > kMaxReadBackPulses) {
    readback_.erase(readback_.begin(),
                    readback_.begin() + static_cast<std::ptrdiff_t>(
                                            std::min(readback_.size(), kMaxReadBackPulses / 2)));
  }
  readback_.insert(readback_.end(), pulses.begin(), pulses.end());
}

std::vector<model::Pulse> SafeBench::DrainDeliveredPulses() {
  std::lock_guard lock(readback_mu_);
  std::vector<model::Pulse> out;
  out.swap(readback_);
  return out;
}

void SafeBench::EStop(const std::string& source) {
  // Hardware first: this is the action that must not wait for anything.
  bench_.HardwareEStop();
  const bool was = estop_.exchange(true);
  if (!was) Emit({SafetyEvent::Kind::kEStop, bench_.Now_s(), kNaN, kNaN, source});
}

void SafeBench::ClearEStop(const std::string& source) {
  if (!estop_.load()) return;
  bench_.ClearHardwareEStop();
  MakeSafe();
  estop_.store(false);
  Emit({SafetyEvent::Kind::kEStopCleared, bench_.Now_s(), kNaN, kNaN, source});
}

bool SafeBench::estopped() const { return estop_.load(); }

void SafeBench::CheckWatchdog() {
  double timeout_s;
  {
    std::lock_guard lock(mu_);
    timeout_s = limits_.heartbeat_timeout_s;
  }
  if (const std::optional<double> silent = watchdog_.Check(timeout_s)) {
    MakeSafe();
    Emit({SafetyEvent::Kind::kWatchdog, bench_.Now_s(), *silent, 0.0,
          "controlling client silent for " + std::to_string(*silent) + " s"});
  }
}

}  // namespace fesbench::server
