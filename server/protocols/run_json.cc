#include "server/protocols/run_json.h"

#include <cmath>

#include "api/parameter_set_json.h"

namespace fesbench::server::protocols {
namespace {

nlohmann::json Number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

}  // namespace

std::string_view SafetyEventKindName(SafetyEvent::Kind kind) {
  switch (kind) {
    case SafetyEvent::Kind::kStimClamped:
      return "stim_clamped";
    case SafetyEvent::Kind::kSetpointClamped:
      return "setpoint_clamped";
    case SafetyEvent::Kind::kEStop:
      return "estop";
    case SafetyEvent::Kind::kEStopCleared:
      return "estop_cleared";
    case SafetyEvent::Kind::kWatchdog:
      return "watchdog";
  }
  return "estop";
}

nlohmann::json SafetyEventToJson(const SafetyEvent& e) {
  return {{"kind", std::string(SafetyEventKindName(e.kind))},
          {"t_s", Number(e.t_s)},
          {"requested", Number(e.requested)},
          {"applied", Number(e.applied)},
          {"detail", e.detail}};
}

nlohmann::json ProgressToJson(const Progress& p) {
  return {{"fraction", p.fraction},
          {"eta_s", Number(p.eta_s)},
          {"bench_elapsed_s", p.bench_elapsed_s},
          {"bench_total_s", p.bench_total_s},
          {"step", p.step},
          {"phase", std::string(StepPhaseName(p.phase))}};
}

nlohmann::json SampleBatchToJson(const SampleBatch& b) {
  nlohmann::json j = {{"trial", b.trial},          {"trial_name", b.trial_name}, {"t_s", b.t_s},
                      {"stim_ma", b.stim_ma},      {"angle_deg", b.angle_deg},
                      {"torque_nm", b.torque_nm},  {"accel_m_s2", b.accel_m_s2}};
  // Tracking runs (issue 19): the target and the controller's τ̂_scale.
  if (!b.target_deg.empty()) j["target_deg"] = b.target_deg;
  if (!b.tau_scale_nm.empty()) j["tau_scale_nm"] = b.tau_scale_nm;
  return j;
}

nlohmann::json RunResultToJson(const RunResult& r) {
  nlohmann::json trials = nlohmann::json::array();
  for (const RecordedTrial& t : r.trials) {
    const std::size_t n = t.trial.num_samples();
    trials.push_back({{"name", t.trial.name.value_or("")},
                      {"samples", n},
                      {"sample_rate_hz", t.trial.sample_rate_hz},
                      {"duration_s", static_cast<double>(n) / t.trial.sample_rate_hz},
                      {"complete", t.complete},
                      {"offsets_nm", t.offsets_nm}});
  }
  nlohmann::json events = nlohmann::json::array();
  for (const SafetyEvent& e : r.safety_events) events.push_back(SafetyEventToJson(e));
  nlohmann::json parameters = nlohmann::json::object();
  for (const auto& [k, v] : r.parameters) parameters[k] = v;
  nlohmann::json values = nlohmann::json::object();
  for (const auto& [k, v] : r.values) values[k] = Number(v);
  nlohmann::json j = {{"state", std::string(RunStateName(r.state))},
                      {"reason", r.reason},
                      {"protocol", r.protocol},
                      {"protocol_version", r.protocol_version},
                      {"parameters", std::move(parameters)},
                      {"trials", std::move(trials)},
                      {"values", std::move(values)},
                      {"safety_events", std::move(events)},
                      {"bench_duration_s", r.bench_duration_s},
                      {"wall_duration_s", r.wall_duration_s}};
  if (r.tolerance) {
    const ToleranceResult& t = *r.tolerance;
    j["tolerance"] = {
        {"threshold_ma", t.threshold_ma ? nlohmann::json(*t.threshold_ma) : nlohmann::json()},
        {"max_tolerated_ma", t.max_tolerated_ma},
        {"max_torque_nm", t.max_torque_nm},
        {"noise_band_nm", t.noise_band_nm},
        {"stopped_by_clinician", t.stopped_by_clinician},
        {"warnings", t.warnings}};
  }
  if (r.parameter_set) j["parameter_set"] = api::ParameterSetToJson(*r.parameter_set);
  return j;
}

}  // namespace fesbench::server::protocols
