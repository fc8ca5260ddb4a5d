#include "api/run.h"

#include <cmath>
#include <limits>
#include <utility>

#include "api/time_utc.h"

namespace fesbench::api {
namespace {

using nlohmann::json;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

json Finite(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

template <typename T>
json Nullable(const std::optional<T>& v) {
  return v ? json(*v) : json(nullptr);
}

json TimeOrNull(const std::optional<UtcTime>& t) {
  return t ? json(FormatUtc(*t)) : json(nullptr);
}

// Reads the fields a client needs from one object: typed, the first
// mistake kept, unknown fields ignored (a newer server may send more).
class Reader {
 public:
  Reader(const json& object, std::string path) : object_(object), path_(std::move(path)) {
    if (!object_.is_object()) Fail("", "must be an object, got " + std::string(object_.type_name()));
  }

  // A number; null (an unknown value) reads as NaN.
  void Number(const char* key, double& out, bool required = false) {
    if (const json* v = Find(key, required)) {
      if (v->is_number()) {
        out = v->get<double>();
      } else if (v->is_null()) {
        out = kNaN;
      } else {
        Fail(key, "must be a number");
      }
    }
  }
  template <typename Int>
  void Integer(const char* key, Int& out, bool required = false) {
    if (const json* v = Find(key, required)) {
      if (v->is_number_integer()) {
        out = v->get<Int>();
      } else {
        Fail(key, "must be an integer");
      }
    }
  }
  template <typename Int>
  void Integer(const char* key, std::optional<Int>& out) {
    if (const json* v = Find(key, false); v != nullptr && !v->is_null()) {
      Int value{};
      Integer(key, value);
      out = value;
    }
  }
  void Text(const char* key, std::string& out) {
    if (const json* v = Find(key, false); v != nullptr && !v->is_null()) {
      if (v->is_string()) {
        out = v->get<std::string>();
      } else {
        Fail(key, "must be a string");
      }
    }
  }
  void Bool(const char* key, bool& out) {
    if (const json* v = Find(key, false)) {
      if (v->is_boolean()) {
        out = v->get<bool>();
      } else {
        Fail(key, "must be true or false");
      }
    }
  }
  template <typename T>
  void Array(const char* key, std::vector<T>& out) {
    if (const json* v = Find(key, false); v != nullptr && !v->is_null()) {
      try {
        out = v->get<std::vector<T>>();
      } catch (const json::exception&) {
        Fail(key, "must be an array of the right type");
      }
    }
  }
  template <typename Enum>
  void Named(const char* key, Enum& out, std::optional<Enum> (*parse)(std::string_view),
             bool required = true) {
    if (const json* v = Find(key, required)) {
      const std::optional<Enum> parsed =
          v->is_string() ? parse(v->get<std::string>()) : std::nullopt;
      if (parsed) {
        out = *parsed;
      } else {
        Fail(key, "unknown value " + v->dump());
      }
    }
  }
  void Time(const char* key, std::optional<UtcTime>& out) {
    if (const json* v = Find(key, false); v != nullptr && !v->is_null()) {
      std::optional<UtcTime> parsed =
          v->is_string() ? ParseUtc(v->get<std::string>()) : std::nullopt;
      if (parsed) {
        out = parsed;
      } else {
        Fail(key, "must be an ISO-8601 UTC time");
      }
    }
  }
  const json* Raw(const char* key) { return Find(key, false); }

  std::string PathOf(std::string_view key) const {
    if (key.empty()) return path_;
    return path_.empty() ? std::string(key) : path_ + "." + std::string(key);
  }
  void Fail(std::string_view key, std::string message) {
    if (status_.ok()) status_ = Status::InvalidArgument(std::move(message), PathOf(key));
  }
  void Adopt(const Status& nested) {
    if (status_.ok() && !nested.ok()) status_ = nested;
  }
  const Status& status() const { return status_; }

 private:
  const json* Find(const char* key, bool required) {
    if (!status_.ok()) return nullptr;
    const auto it = object_.find(key);
    if (it == object_.end()) {
      if (required) Fail(key, "is required");
      return nullptr;
    }
    return &*it;
  }

  const json& object_;
  std::string path_;
  Status status_;
};

template <typename T>
Result<T> Finish(const Reader& reader, T value) {
  if (!reader.status().ok()) return reader.status();
  return value;
}

Progress ReadProgress(Reader& in, const json& object, const std::string& path) {
  Result<Progress> progress = ProgressFromJson(object);
  if (!progress.ok()) {
    in.Adopt(Status::InvalidArgument(progress.status().message(),
                                     path + "." + progress.status().field()));
    return {};
  }
  return *progress;
}

}  // namespace

std::string_view StepPhaseName(StepPhase phase) {
  switch (phase) {
    case StepPhase::kPrepare: return "prepare";
    case StepPhase::kOffset: return "offset";
    case StepPhase::kStimulate: return "stimulate";
    case StepPhase::kRest: return "rest";
    case StepPhase::kMove: return "move";
    case StepPhase::kIdentify: return "identify";
  }
  return "rest";
}

std::optional<StepPhase> ParseStepPhase(std::string_view name) {
  for (StepPhase phase : {StepPhase::kPrepare, StepPhase::kOffset, StepPhase::kStimulate,
                          StepPhase::kRest, StepPhase::kMove, StepPhase::kIdentify}) {
    if (StepPhaseName(phase) == name) return phase;
  }
  return std::nullopt;
}

json ProgressToJson(const Progress& p) {
  return {{"fraction", p.fraction},
          {"eta_s", Finite(p.eta_s)},
          {"bench_elapsed_s", p.bench_elapsed_s},
          {"bench_total_s", p.bench_total_s},
          {"step", p.step},
          {"phase", std::string(StepPhaseName(p.phase))}};
}

Result<Progress> ProgressFromJson(const json& j) {
  Reader in(j, "");
  Progress p;
  in.Number("fraction", p.fraction, true);
  in.Number("eta_s", p.eta_s);
  in.Number("bench_elapsed_s", p.bench_elapsed_s);
  in.Number("bench_total_s", p.bench_total_s);
  in.Integer("step", p.step);
  in.Named("phase", p.phase, &ParseStepPhase, false);
  return Finish(in, p);
}

std::string_view SafetyEventKindName(SafetyEvent::Kind kind) {
  switch (kind) {
    case SafetyEvent::Kind::kStimClamped: return "stim_clamped";
    case SafetyEvent::Kind::kSetpointClamped: return "setpoint_clamped";
    case SafetyEvent::Kind::kEStop: return "estop";
    case SafetyEvent::Kind::kEStopCleared: return "estop_cleared";
    case SafetyEvent::Kind::kWatchdog: return "watchdog";
  }
  return "estop";
}

std::optional<SafetyEvent::Kind> ParseSafetyEventKind(std::string_view name) {
  using Kind = SafetyEvent::Kind;
  for (Kind kind : {Kind::kStimClamped, Kind::kSetpointClamped, Kind::kEStop,
                    Kind::kEStopCleared, Kind::kWatchdog}) {
    if (SafetyEventKindName(kind) == name) return kind;
  }
  return std::nullopt;
}

json SafetyEventToJson(const SafetyEvent& e) {
  return {{"kind", std::string(SafetyEventKindName(e.kind))},
          {"t_s", Finite(e.t_s)},
          {"requested", Finite(e.requested)},
          {"applied", Finite(e.applied)},
          {"detail", e.detail}};
}

Result<SafetyEvent> SafetyEventFromJson(const json& j) {
  Reader in(j, "");
  SafetyEvent e;
  in.Named("kind", e.kind, &ParseSafetyEventKind);
  in.Number("t_s", e.t_s);
  in.Number("requested", e.requested);
  in.Number("applied", e.applied);
  in.Text("detail", e.detail);
  return Finish(in, e);
}

json SampleBatchToJson(const SampleBatch& b) {
  json j = {{"trial", b.trial},         {"trial_name", b.trial_name}, {"t_s", b.t_s},
            {"stim_ma", b.stim_ma},     {"angle_deg", b.angle_deg},   {"torque_nm", b.torque_nm},
            {"accel_m_s2", b.accel_m_s2}};
  if (!b.target_deg.empty()) j["target_deg"] = b.target_deg;
  if (!b.tau_scale_nm.empty()) j["tau_scale_nm"] = b.tau_scale_nm;
  return j;
}

Result<SampleBatch> SampleBatchFromJson(const json& j) {
  Reader in(j, "");
  SampleBatch b;
  in.Integer("trial", b.trial);
  in.Text("trial_name", b.trial_name);
  in.Array("t_s", b.t_s);
  in.Array("stim_ma", b.stim_ma);
  in.Array("angle_deg", b.angle_deg);
  in.Array("torque_nm", b.torque_nm);
  in.Array("accel_m_s2", b.accel_m_s2);
  in.Array("target_deg", b.target_deg);
  in.Array("tau_scale_nm", b.tau_scale_nm);
  return Finish(in, b);
}

json ToleranceResultToJson(const ToleranceResult& t) {
  return {{"threshold_ma", Nullable(t.threshold_ma)},
          {"max_tolerated_ma", t.max_tolerated_ma},
          {"max_torque_nm", t.max_torque_nm},
          {"noise_band_nm", t.noise_band_nm},
          {"stopped_by_clinician", t.stopped_by_clinician},
          {"warnings", t.warnings}};
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
            {"trial_ids", v.trial_ids},
            {"parameter_set_id", Nullable(v.parameter_set_id)},
            {"values", std::move(values)},
            {"safety_events", std::move(events)},
            {"live", v.live}};
  if (v.tolerance) j["tolerance"] = ToleranceResultToJson(*v.tolerance);
  return j;
}

Result<RunView> RunViewFromJson(const json& j) {
  Reader in(j, "");
  RunView v;
  in.Integer("run_id", v.run_id, true);
  in.Integer("session_id", v.session_id);
  in.Text("protocol", v.protocol);
  in.Integer("protocol_version", v.protocol_version);
  if (const json* parameters = in.Raw("parameters"); parameters != nullptr && parameters->is_object()) {
    for (const auto& [k, x] : parameters->items()) {
      if (x.is_number()) v.parameters[k] = x.get<double>();
    }
  }
  in.Named("state", v.state, &ParseRunState);
  in.Text("reason", v.reason);
  in.Number("progress", v.progress.fraction);
  v.progress.eta_s = kNaN;
  in.Number("eta_s", v.progress.eta_s);
  std::optional<UtcTime> created;
  in.Time("created_at_utc", created);
  if (created) v.created_at = *created;
  in.Time("started_at_utc", v.started_at);
  in.Time("finished_at_utc", v.finished_at);
  if (const json* result = in.Raw("result")) v.result = *result;
  in.Text("controller", v.owner);
  in.Number("bench_elapsed_s", v.progress.bench_elapsed_s);
  in.Number("bench_total_s", v.progress.bench_total_s);
  in.Array("trial_ids", v.trial_ids);
  in.Integer("parameter_set_id", v.parameter_set_id);
  if (const json* values = in.Raw("values"); values != nullptr && values->is_object()) {
    for (const auto& [k, x] : values->items()) v.values[k] = x.is_number() ? x.get<double>() : kNaN;
  }
  if (const json* events = in.Raw("safety_events"); events != nullptr && events->is_array()) {
    for (std::size_t i = 0; i < events->size(); ++i) {
      Result<SafetyEvent> e = SafetyEventFromJson((*events)[i]);
      if (!e.ok()) {
        in.Fail("safety_events[" + std::to_string(i) + "]", e.status().message());
        break;
      }
      v.safety_events.push_back(*std::move(e));
    }
  }
  in.Bool("live", v.live);
  return Finish(in, std::move(v));
}

json BenchStateToJson(const BenchState& s) {
  return {{"kind", s.kind},
          {"mode", s.mode},
          {"busy", s.busy},
          {"estopped", s.estopped},
          {"estop_source", s.estop_source},
          {"owner", s.owner},
          {"owner_user_id", Nullable(s.owner_user_id)},
          {"run_id", Nullable(s.run_id)},
          {"protocol", s.protocol},
          {"run_state", std::string(RunStateName(s.run_state))},
          {"progress", ProgressToJson(s.progress)}};
}

Result<BenchState> BenchStateFromJson(const json& j) {
  Reader in(j, "");
  BenchState s;
  in.Text("kind", s.kind);
  in.Text("mode", s.mode);
  in.Bool("busy", s.busy);
  in.Bool("estopped", s.estopped);
  in.Text("estop_source", s.estop_source);
  in.Text("owner", s.owner);
  in.Integer("owner_user_id", s.owner_user_id);
  in.Integer("run_id", s.run_id);
  in.Text("protocol", s.protocol);
  in.Named("run_state", s.run_state, &ParseRunState, false);
  if (const json* progress = in.Raw("progress")) s.progress = ReadProgress(in, *progress, "progress");
  return Finish(in, std::move(s));
}

std::string_view RunEventKindName(RunEvent::Kind kind) {
  switch (kind) {
    case RunEvent::Kind::kState: return "state";
    case RunEvent::Kind::kProgress: return "progress";
    case RunEvent::Kind::kSamples: return "samples";
    case RunEvent::Kind::kTrial: return "trial";
    case RunEvent::Kind::kEnd: return "end";
    case RunEvent::Kind::kParameterSet: return "parameter_set";
  }
  return "state";
}

std::optional<RunEvent::Kind> ParseRunEventKind(std::string_view name) {
  using Kind = RunEvent::Kind;
  for (Kind kind : {Kind::kState, Kind::kProgress, Kind::kSamples, Kind::kTrial, Kind::kEnd,
                    Kind::kParameterSet}) {
    if (RunEventKindName(kind) == name) return kind;
  }
  return std::nullopt;
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
      j["trial_id"] = Nullable(e.trial_id);
      break;
    case RunEvent::Kind::kEnd:
      j["state"] = std::string(RunStateName(e.state));
      j["reason"] = e.reason;
      j["parameter_set_id"] = Nullable(e.parameter_set_id);
      j["result"] = e.result;
      break;
    case RunEvent::Kind::kParameterSet:
      j["parameter_set_id"] = Nullable(e.parameter_set_id);
      j["subject_id"] = e.subject_id;
      j["leg_id"] = e.leg_id;
      break;
  }
  return j;
}

Result<RunEvent> RunEventFromJson(const json& j) {
  Reader in(j, "");
  RunEvent e;
  in.Named("kind", e.kind, &ParseRunEventKind);
  in.Integer("seq", e.seq);
  in.Integer("run_id", e.run_id);
  if (!in.status().ok()) return in.status();
  const bool has_state = e.kind == RunEvent::Kind::kState || e.kind == RunEvent::Kind::kEnd;
  if (has_state) {
    in.Named("state", e.state, &ParseRunState);
    in.Text("reason", e.reason);
  }
  if (const json* progress = in.Raw("progress")) e.progress = ReadProgress(in, *progress, "progress");
  if (const json* samples = in.Raw("samples")) {
    Result<SampleBatch> batch = SampleBatchFromJson(*samples);
    if (batch.ok()) {
      e.samples = *std::move(batch);
    } else {
      in.Fail("samples", batch.status().ToString());
    }
  }
  in.Integer("first_sample", e.first_sample);
  in.Integer("trial", e.samples.trial);
  in.Text("trial_name", e.samples.trial_name);
  in.Integer("trial_id", e.trial_id);
  in.Integer("parameter_set_id", e.parameter_set_id);
  in.Integer("subject_id", e.subject_id);
  in.Integer("leg_id", e.leg_id);
  if (const json* result = in.Raw("result")) e.result = *result;
  return Finish(in, std::move(e));
}

}  // namespace fesbench::api
