#include "server/protocols/tracking_loop.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <vector>

#include "api/model_call.h"

namespace fesbench::server::protocols {
namespace {

constexpr double kSampleRateHz = 200.0;  // the controller's rate (the trials')

}  // namespace

api::Result<TrackingLoop> TrackingLoop::Create(const TrackingSettings& settings,
                                               double start_angle_deg) {
  api::Result<model::KneeTarget> target = api::CallModel(
      [&] { return model::WithLeadIn(settings.target, start_angle_deg, settings.lead_in_s); });
  if (!target.ok()) return target.status();
  TrackingLoop loop(settings);
  if (settings.params) {
    if (api::Status st = api::CallModel([&] {
          loop.controller_.emplace(*settings.params, std::move(target).value(), settings.options);
        });
        !st.ok()) {
      return st;
    }
    return loop;
  }
  const model::TrackingOptions& o = settings.options;
  if (o.kind != model::ControllerKind::kPid || !o.gains) {
    return api::Status::InvalidArgument(
        "only pid with its gains given runs without a parameter set");
  }
  if (!(std::isfinite(o.threshold_ma) && o.threshold_ma >= 0.0 &&
        std::isfinite(o.max_amplitude_ma) && o.max_amplitude_ma >= o.threshold_ma)) {
    return api::Status::InvalidArgument("need 0 ≤ threshold_ma ≤ max_amplitude_ma");
  }
  if (target->angle_deg.empty() || !(target->rate_hz > 0.0)) {
    return api::Status::InvalidArgument("the target is empty");
  }
  loop.target_ = std::move(target).value();
  if (api::Status st = api::CallModel([&] {
        loop.pid_.emplace(*o.gains, 1.0 / loop.target_.rate_hz, 0.0, o.max_amplitude_ma);
        loop.oscillation_.emplace(loop.target_.rate_hz, model::OscillationDetector::Options{});
      });
      !st.ok()) {
    return st;
  }
  return loop;
}

model::TrackingSample TrackingLoop::UpdateModelFreePid(double measured_deg) {
  const std::size_t i = std::min(index_, target_.angle_deg.size() - 1);
  model::TrackingSample s;
  s.target_deg = target_.angle_deg[i];
  s.error_deg = measured_deg - s.target_deg;
  s.feedforward_ma = settings_.options.threshold_ma;
  s.amplitude_ma = pid_->Update(s.target_deg, measured_deg, s.feedforward_ma);
  s.correction_ma = s.amplitude_ma - s.feedforward_ma;
  s.tau_scale_nm = 0.0;  // no set
  s.saturated =
      (s.amplitude_ma >= settings_.options.max_amplitude_ma - 1e-9 || pid_->saturated_high()) &&
      s.error_deg > 0.0;
  model::BackOffOnOscillation(*oscillation_, *pid_, backoffs_, s);
  return s;
}

std::optional<std::string> TrackingLoop::Sample(double measured_deg) {
  // The one input the controllers cannot take once built (model::TrackingController::Update
  // requires it): the run ends, as for a saturated or oscillating loop.
  if (!std::isfinite(measured_deg)) return "tracking: the measured angle is not finite";
  last_ = controller_ ? controller_->Update(measured_deg) : UpdateModelFreePid(measured_deg);
  ++index_;
  // Below the controller: the slew limit (SafeBench then clamps the
  // maximum), on the recruiting range only. An amplitude at or below the
  // threshold recruits nothing, so stimulation turns on at the threshold
  // and off from it at once; only the change above it is limited (a 0 ↔
  // threshold step held to the limit is a dead time of threshold/limit,
  // 0.3 s at 75 mA/s, that the loop's margin never saw).
  const double step_ma = settings_.max_rate_ma_per_s / kSampleRateHz;
  const double floor_ma = std::max(settings_.options.threshold_ma, 0.0);
  const double from = std::max(amplitude_ma_, floor_ma);
  const double limited =
      std::clamp(std::max(last_.amplitude_ma, floor_ma), from - step_ma, from + step_ma);
  amplitude_ma_ = limited <= floor_ma && last_.amplitude_ma <= floor_ma ? last_.amplitude_ma
                                                                        : limited;
  saturated_samples_ = last_.saturated ? saturated_samples_ + 1 : 0;
  if (last_.saturated) saturated_total_s_ += 1.0 / kSampleRateHz;
  if (static_cast<double>(index_) > settings_.lead_in_s * kSampleRateHz) {
    if (amplitude_ma_ <= 0.0) zero_s_ += 1.0 / kSampleRateHz;
    if (amplitude_ma_ >= settings_.options.max_amplitude_ma - 1e-9)
      at_max_s_ += 1.0 / kSampleRateHz;
  }
  std::ostringstream why;
  if (last_.oscillating) {
    const model::Pid::Gains& g = controller_ ? controller_->current_gains() : pid_->gains();
    why << "tracking: the knee still oscillates (swings of at least 4° faster than every 3 s) "
        << "after the loop gains were halved " << model::kMaxOscillationBackoffs
        << " times (kp now " << g.kp << "); the run is stopped";
    return why.str();
  }
  if (static_cast<double>(saturated_samples_) / kSampleRateHz <= settings_.max_saturation_s) {
    return std::nullopt;
  }
  why << "tracking: the controller asked for more than the maximum "
      << settings_.options.max_amplitude_ma << " mA for " << settings_.max_saturation_s
      << " s (target " << last_.target_deg << "°, knee at " << last_.target_deg + last_.error_deg
      << "°): the leg cannot follow this target";
  return why.str();
}

void TrackingLoop::Summarise(const api::Trial& trial, std::map<std::string, double>& values) const {
  const auto lead = static_cast<std::size_t>(std::llround(settings_.lead_in_s * kSampleRateHz));
  if (const std::vector<double>* angle = trial.Values("angle_deg");
      angle != nullptr && angle->size() > lead) {
    const model::TrackingMetrics m = model::MeasureTracking(
        settings_.target,
        std::vector<double>(angle->begin() + static_cast<std::ptrdiff_t>(lead), angle->end()));
    values["tracking_rms_deg"] = m.rms_deg;
    values["tracking_max_error_deg"] = m.max_error_deg;
    if (m.overshoot_deg) values["overshoot_deg"] = *m.overshoot_deg;
    if (m.settling_s) values["settling_s"] = *m.settling_s;
    if (m.worst_overshoot_deg) values["worst_overshoot_deg"] = *m.worst_overshoot_deg;
    if (m.worst_settling_s) values["worst_settling_s"] = *m.worst_settling_s;
    values["error_rms_above_1hz_deg"] = m.rms_above_1hz_deg;
  }
  values["zero_ma_s"] = zero_s_;
  values["max_ma_s"] = at_max_s_;
  values["oscillation_backoffs"] = controller_ ? controller_->backoffs() : backoffs_;
  // Charge: Σ amplitude × pulse width of what the stimulator delivered.
  double charge_nc = 0.0;
  if (trial.pulses) {
    for (double ma : trial.pulses->stim_ma) charge_nc += ma * trial.pulses->pulse_width_us;
  }
  values["charge_uc"] = charge_nc / 1000.0;
  values["saturated_s"] = saturated_total_s_;
  if (controller_) values["tau_scale_nm"] = controller_->tau_scale_nm();
  if (settings_.reachable_extension_deg) {
    values["reachable_extension_deg"] = *settings_.reachable_extension_deg;
  }
  const model::Pid::Gains& g = controller_ ? controller_->gains() : *settings_.options.gains;
  const bool amplitude = settings_.options.kind == model::ControllerKind::kPid;
  values[amplitude ? "kp_ma_per_deg" : "kp_nm_per_deg"] = g.kp;
  values[amplitude ? "ki_ma_per_deg_s" : "ki_nm_per_deg_s"] = g.ki;
  values[amplitude ? "kd_ma_s_per_deg" : "kd_nm_s_per_deg"] = g.kd;
}

}  // namespace fesbench::server::protocols
