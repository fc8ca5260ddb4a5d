#include "api/run.h"

#include <cmath>
#include <limits>
#include <utility>

#include "api/json_fields.h"
#include "api/json_read.h"
#include "api/name_table.h"
#include "api/time_utc.h"

namespace fesbench::api {
namespace {

using nlohmann::json;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

constexpr NameTable<StepPhase, 6> kStepPhases({{{StepPhase::kPrepare, "prepare"},
                                                {StepPhase::kOffset, "offset"},
                                                {StepPhase::kStimulate, "stimulate"},
                                                {StepPhase::kRest, "rest"},
                                                {StepPhase::kMove, "move"},
                                                {StepPhase::kIdentify, "identify"}}},
                                              "rest");

constexpr NameTable<SafetyEvent::Kind, 5> kSafetyEventKinds(
    {{{SafetyEvent::Kind::kStimClamped, "stim_clamped"},
      {SafetyEvent::Kind::kSetpointClamped, "setpoint_clamped"},
      {SafetyEvent::Kind::kEStop, "estop"},
      {SafetyEvent::Kind::kEStopCleared, "estop_cleared"},
      {SafetyEvent::Kind::kWatchdog, "watchdog"}}},
    "estop");

constexpr NameTable<RunEvent::Kind, 6> kRunEventKinds({{{RunEvent::Kind::kState, "state"},
                                                        {RunEvent::Kind::kProgress, "progress"},
                                                        {RunEvent::Kind::kSamples, "samples"},
                                                        {RunEvent::Kind::kTrial, "trial"},
                                                        {RunEvent::Kind::kEnd, "end"},
                                                        {RunEvent::Kind::kParameterSet,
                                                         "parameter_set"}}},
                                                      "state");

json Finite(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

json TimeOrNull(const std::optional<UtcTime>& t) { return t ? json(FormatUtc(*t)) : json(nullptr); }

}  // namespace

std::string_view StepPhaseName(StepPhase phase) { return kStepPhases.Name(phase); }

std::optional<StepPhase> ParseStepPhase(std::string_view name) { return kStepPhases.Parse(name); }

json ProgressToJson(const Progress& p) {
  return {{"fraction", p.fraction},
          {"eta_s", Finite(p.eta_s)},
          {"bench_elapsed_s", p.bench_elapsed_s},
          {"bench_total_s", p.bench_total_s},
          {"bench_planned_s", Finite(p.bench_planned_s)},
          {"step", p.step},
          {"phase", std::string(StepPhaseName(p.phase))}};
}

Result<Progress> ProgressFromJson(const json& j) {
  JsonFields in(j);
  Progress p;
  p.eta_s = kNaN;  // null or absent: unknown
  p.fraction = in.Number("fraction", true).value_or(0.0);
  ReadInto(in, "eta_s", p.eta_s);
  ReadInto(in, "bench_elapsed_s", p.bench_elapsed_s);
  ReadInto(in, "bench_total_s", p.bench_total_s);
  ReadInto(in, "bench_planned_s", p.bench_planned_s);  // null or absent: unknown
  ReadInto(in, "step", p.step);
  ReadNamed(in, "phase", false, p.phase, &ParseStepPhase);
  return ReadResult(in, p);
}

std::string_view SafetyEventKindName(SafetyEvent::Kind kind) {
  return kSafetyEventKinds.Name(kind);
}

std::optional<SafetyEvent::Kind> ParseSafetyEventKind(std::string_view name) {
  return kSafetyEventKinds.Parse(name);
}

json SafetyEventToJson(const SafetyEvent& e) {
  return {{"kind", std::string(SafetyEventKindName(e.kind))},
          {"t_s", Finite(e.t_s)},
          {"requested", Finite(e.requested)},
          {"applied", Finite(e.applied)},
          {"detail", e.detail}};
}

Result<SafetyEvent> SafetyEventFromJson(const json& j) {
  JsonFields in(j);
  SafetyEvent e;
  e.t_s = e.requested = e.applied = kNaN;  // null: not applicable
  ReadNamed(in, "kind", true, e.kind, &ParseSafetyEventKind);
  ReadInto(in, "t_s", e.t_s);
  ReadInto(in, "requested", e.requested);
  ReadInto(in, "applied", e.applied);
  ReadInto(in, "detail", e.detail);
  return ReadResult(in, e);
}

json SampleBatchToJson(const SampleBatch& b) {
  json j = {{"trial", b.trial},          {"trial_name", b.trial_name}, {"t_s", b.t_s},
            {"stim_ma", b.stim_ma},      {"angle_deg", b.angle_deg},   {"torque_nm", b.torque_nm},
            {"accel_m_s2", b.accel_m_s2}};
  if (!b.target_deg.empty()) j["target_deg"] = b.target_deg;
  if (!b.tau_scale_nm.empty()) j["tau_scale_nm"] = b.tau_scale_nm;
  return j;
}

Result<SampleBatch> SampleBatchFromJson(const json& j) {
  JsonFields in(j);
  SampleBatch b;
  ReadInto(in, "trial", b.trial);
  ReadInto(in, "trial_name", b.trial_name);
  ReadInto(in, "t_s", b.t_s);
  ReadInto(in, "stim_ma", b.stim_ma);
  ReadInto(in, "angle_deg", b.angle_deg);
  ReadInto(in, "torque_nm", b.torque_nm);
  ReadInto(in, "accel_m_s2", b.accel_m_s2);
  ReadInto(in, "target_deg", b.target_deg);
  ReadInto(in, "tau_scale_nm", b.tau_scale_nm);
  return ReadResult(in, b);
}

json RunViewToJson(const RunView& v) {
  json parameters = json::object();
  for (const auto& [k, x] : v.parameters) parameters[k] = x;
  json values = json::object();
  for (const auto& [k, x] : v.values) values[k] = Finite(x);
  json events = json::array();
  for (const SafetyEvent& e : v.safety_events) events.push_back(SafetyEventToJson(e));
  const double eta = v.progress.eta_s;
  json j = {{"run_id", v.run_id},
            {"session_id", v.session_id},
            {"protocol", v.protocol},
            {"protocol_version", v.protocol_version},
            {"parameters", std::move(parameters)},
            {"state", std::string(RunStateName(v.state))},
            {"reason", v.reason},
            {"progress", v.progress.fraction},
            {"eta_s", std::isfinite(eta) && eta >= 0.0 ? json(eta) : json(nullptr)},
            {"created_at_utc", FormatUtc(v.created_at)},
            {"started_at_utc", TimeOrNull(v.started_at)},
            {"finished_at_utc", TimeOrNull(v.finished_at)},
            {"result", v.result},
            {"controller", v.owner.empty() ? json(nullptr) : json(v.owner)},
            {"bench_elapsed_s", v.progress.bench_elapsed_s},
            {"bench_total_s", v.progress.bench_total_s},
            {"bench_planned_s", Finite(v.progress.bench_planned_s)},
            {"trial_ids", v.trial_ids},
            {"parameter_set_id", OrNull(v.parameter_set_id)},
            {"used_parameter_set_id", OrNull(v.used_parameter_set_id)},
            {"values", std::move(values)},
            {"safety_events", std::move(events)},
            {"live", v.live},
            {"outcome", v.outcome ? RunOutcomeToJson(*v.outcome) : json(nullptr)}};
  if (v.tolerance) j["tolerance"] = ToleranceResultToJson(*v.tolerance);
  return j;
}

void ShowOutcome(const RunOutcome& outcome, RunView& view) {
  view.state = outcome.state;
  view.reason = outcome.reason;
  view.parameter_set_id = outcome.parameter_set_id;
  if (outcome.used_parameter_set_id) view.used_parameter_set_id = outcome.used_parameter_set_id;
  view.tolerance.reset();
  if (outcome.tolerance && outcome.tolerance->test) view.tolerance = outcome.tolerance->test;
  view.values = RunValuesOf(outcome);
  view.result = RunResultJsonOf(outcome);
  view.outcome = outcome;
}

std::optional<std::int64_t> UsedParameterSetOf(const ParameterValues& parameters) {
  const auto it = parameters.find("parameter_set_id");
  if (it == parameters.end() || !std::isfinite(it->second) || !(it->second >= 1.0) ||
      it->second > 9007199254740992.0) {
    return std::nullopt;
  }
  return static_cast<std::int64_t>(it->second);
}

Result<RunView> RunViewFromJson(const json& j) {
  JsonFields in(j);
  RunView v;
  v.run_id = in.Integer("run_id", true).value_or(0);
  ReadInto(in, "session_id", v.session_id);
  ReadInto(in, "protocol", v.protocol);
  ReadInto(in, "protocol_version", v.protocol_version);
  if (const json* parameters = in.Object("parameters", false)) {
    JsonFields p(*parameters, in.PathOf("parameters"));
    for (const auto& [name, value] : parameters->items()) ReadInto(p, name, v.parameters[name]);
    if (!p.ok()) in.Fail("parameters", p.status().message());
  }
  ReadNamed(in, "state", true, v.state, &ParseRunState);
  ReadInto(in, "reason", v.reason);
  ReadInto(in, "progress", v.progress.fraction);
  v.progress.eta_s = kNaN;  // null: unknown
  ReadInto(in, "eta_s", v.progress.eta_s);
  std::optional<UtcTime> created;
  ReadTime(in, "created_at_utc", created);
  if (created) v.created_at = *created;
  ReadTime(in, "started_at_utc", v.started_at);
  ReadTime(in, "finished_at_utc", v.finished_at);
  if (const json* result = in.Any("result", false)) v.result = *result;
  ReadInto(in, "controller", v.owner);
  ReadInto(in, "bench_elapsed_s", v.progress.bench_elapsed_s);
  ReadInto(in, "bench_total_s", v.progress.bench_total_s);
  ReadInto(in, "bench_planned_s", v.progress.bench_planned_s);
  ReadInto(in, "trial_ids", v.trial_ids);
  ReadInto(in, "parameter_set_id", v.parameter_set_id);
  ReadInto(in, "used_parameter_set_id", v.used_parameter_set_id);
  if (const json* values = in.Object("values", false)) {
    for (const auto& [name, value] : values->items()) {
      v.values[name] = value.is_number() ? value.get<double>() : kNaN;
    }
  }
  if (const json* events = in.Any("safety_events", false)) {
    if (!events->is_array()) in.Fail("safety_events", "must be an array");
    for (std::size_t i = 0; in.ok() && events->is_array() && i < events->size(); ++i) {
      Result<SafetyEvent> e = SafetyEventFromJson((*events)[i]);
      if (!e.ok()) {
        in.Fail("safety_events[" + std::to_string(i) + "]." + e.status().field(),
                e.status().message());
      } else {
        v.safety_events.push_back(*std::move(e));
      }
    }
  }
  ReadInto(in, "live", v.live);
  if (const json* outcome = in.Any("outcome", false)) {
    Result<RunOutcome> read = RunOutcomeFromJson(*outcome);
    if (!read.ok()) {
      in.Fail("outcome." + read.status().field(), read.status().message());
    } else {
      v.outcome = *std::move(read);
      if (v.outcome->tolerance) v.tolerance = v.outcome->tolerance->test;
    }
  }
  return ReadResult(in, std::move(v));
}

json BenchStateToJson(const BenchState& s) {
  return {{"kind", s.kind},
          {"mode", s.mode},
          {"busy", s.busy},
          {"estopped", s.estopped},
          {"estop_source", s.estop_source},
          {"owner", s.owner},
          {"owner_user_id", OrNull(s.owner_user_id)},
          {"run_id", OrNull(s.run_id)},
          {"protocol", s.protocol},
          {"run_state", std::string(RunStateName(s.run_state))},
          {"progress", ProgressToJson(s.progress)}};
}

Result<BenchState> BenchStateFromJson(const json& j) {
  JsonFields in(j);
  BenchState s;
  ReadInto(in, "kind", s.kind);
  ReadInto(in, "mode", s.mode);
  ReadInto(in, "busy", s.busy);
  ReadInto(in, "estopped", s.estopped);
  ReadInto(in, "estop_source", s.estop_source);
  ReadInto(in, "owner", s.owner);
  ReadInto(in, "owner_user_id", s.owner_user_id);
  ReadInto(in, "run_id", s.run_id);
  ReadInto(in, "protocol", s.protocol);
  ReadNamed(in, "run_state", false, s.run_state, &ParseRunState);
  ReadNested(in, "progress", false, s.progress, &ProgressFromJson);
  return ReadResult(in, std::move(s));
}

std::string_view RunEventKindName(RunEvent::Kind kind) { return kRunEventKinds.Name(kind); }

std::optional<RunEvent::Kind> ParseRunEventKind(std::string_view name) {
  return kRunEventKinds.Parse(name);
}

json RunEventToJson(const RunEvent& e) {
  json j = {{"seq", e.seq}, {"run_id", e.run_id}, {"kind", std::string(RunEventKindName(e.kind))}};
  switch (e.kind) {
    case RunEvent::Kind::kState:
      j["state"] = std::string(RunStateName(e.state));
      j["reason"] = e.reason;
      j["progress"] = ProgressToJson(e.progress);
      break;
    case RunEvent::Kind::kProgress:
      j["progress"] = ProgressToJson(e.progress);
      break;
    case RunEvent::Kind::kSamples:
      j["first_sample"] = e.first_sample;
      j["samples"] = SampleBatchToJson(e.samples);
      break;
    case RunEvent::Kind::kTrial:
      j["trial"] = e.samples.trial;
      j["trial_name"] = e.samples.trial_name;
      j["trial_id"] = OrNull(e.trial_id);
      break;
    case RunEvent::Kind::kEnd:
      j["state"] = std::string(RunStateName(e.state));
      j["reason"] = e.reason;
      j["parameter_set_id"] = OrNull(e.parameter_set_id);
      j["result"] = e.result;
      break;
    case RunEvent::Kind::kParameterSet:
      j["parameter_set_id"] = OrNull(e.parameter_set_id);
      j["subject_id"] = e.subject_id;
      j["leg_id"] = e.leg_id;
      if (e.approval) j["approval"] = true;
      break;
  }
  return j;
}

Result<RunEvent> RunEventFromJson(const json& j) {
  JsonFields in(j);
  RunEvent e;
  ReadNamed(in, "kind", true, e.kind, &ParseRunEventKind);
  ReadInto(in, "seq", e.seq);
  ReadInto(in, "run_id", e.run_id);
  if (e.kind == RunEvent::Kind::kState || e.kind == RunEvent::Kind::kEnd) {
    ReadNamed(in, "state", true, e.state, &ParseRunState);
    ReadInto(in, "reason", e.reason);
  }
  ReadNested(in, "progress", false, e.progress, &ProgressFromJson);
  ReadNested(in, "samples", false, e.samples, &SampleBatchFromJson);
  ReadInto(in, "first_sample", e.first_sample);
  ReadInto(in, "trial", e.samples.trial);
  ReadInto(in, "trial_name", e.samples.trial_name);
  ReadInto(in, "trial_id", e.trial_id);
  ReadInto(in, "parameter_set_id", e.parameter_set_id);
  ReadInto(in, "subject_id", e.subject_id);
  ReadInto(in, "leg_id", e.leg_id);
  ReadInto(in, "approval", e.approval);
  if (const json* result = in.Any("result", false)) e.result = *result;
  return ReadResult(in, std::move(e));
}

}  // namespace fesbench::api
