#include "api/run_outcome.h"

#include <cmath>
#include <utility>

#include "api/json_fields.h"
#include "api/json_read.h"

namespace fesbench::api {
namespace {

using nlohmann::json;

json FiniteOrNull(const std::optional<double>& v) {
  return v && std::isfinite(*v) ? json(*v) : json(nullptr);
}

// A nested object read by `from`, its failure named by the nested path.
void PutIfKnown(json& j, const char* key, const std::optional<double>& v) {
  if (v) j[key] = FiniteOrNull(v);
}

double AsNumber(bool b) { return b ? 1.0 : 0.0; }

}  // namespace

json ToleranceResultToJson(const ToleranceResult& t) {
  return {{"threshold_ma", OrNull(t.threshold_ma)},
          {"max_tolerated_ma", t.max_tolerated_ma},
          {"max_torque_nm", t.max_torque_nm},
          {"noise_band_nm", t.noise_band_nm},
          {"stopped_by_clinician", t.stopped_by_clinician},
          {"warnings", t.warnings}};
}

Result<ToleranceResult> ToleranceResultFromJson(const json& j) {
  JsonFields in(j);
  ToleranceResult t;
  ReadInto(in, "threshold_ma", t.threshold_ma);
  if (const auto max = in.Number("max_tolerated_ma", true)) t.max_tolerated_ma = *max;
  ReadInto(in, "max_torque_nm", t.max_torque_nm);
  ReadInto(in, "noise_band_nm", t.noise_band_nm);
  ReadInto(in, "stopped_by_clinician", t.stopped_by_clinician);
  ReadInto(in, "warnings", t.warnings);
  return ReadResult(in, std::move(t));
}

json ToleranceOutcomeToJson(const ToleranceOutcome& t) {
  json j = {{"threshold_ma", OrNull(t.threshold_ma)},
            {"max_tolerated_ma", OrNull(t.max_tolerated_ma)},
            {"ended_at_ceiling", t.ended_at_ceiling},
            {"message", t.message}};
  if (t.test) j["test"] = ToleranceResultToJson(*t.test);
  if (t.subject_signalled_limit) j["subject_signalled_limit"] = *t.subject_signalled_limit;
  return j;
}

Result<ToleranceOutcome> ToleranceOutcomeFromJson(const json& j) {
  JsonFields in(j);
  ToleranceOutcome t;
  ReadNested(in, "test", false, t.test, &ToleranceResultFromJson);
  ReadInto(in, "threshold_ma", t.threshold_ma);
  ReadInto(in, "max_tolerated_ma", t.max_tolerated_ma);
  t.subject_signalled_limit = in.Bool("subject_signalled_limit", false);
  ReadInto(in, "ended_at_ceiling", t.ended_at_ceiling);
  ReadInto(in, "message", t.message);
  return ReadResult(in, std::move(t));
}

json AmplitudeSearchOutcomeToJson(const AmplitudeSearchOutcome& a) {
  json j = json::object();
  PutIfKnown(j, "rb_amplitude_ma", a.rb_amplitude_ma);
  PutIfKnown(j, "full_extension_amplitude_ma", a.full_extension_amplitude_ma);
  if (a.full_extension_reached) j["full_extension_reached"] = *a.full_extension_reached;
  return j;
}

Result<AmplitudeSearchOutcome> AmplitudeSearchOutcomeFromJson(const json& j) {
  JsonFields in(j);
  AmplitudeSearchOutcome a;
  ReadInto(in, "rb_amplitude_ma", a.rb_amplitude_ma);
  ReadInto(in, "full_extension_amplitude_ma", a.full_extension_amplitude_ma);
  a.full_extension_reached = in.Bool("full_extension_reached", false);
  return ReadResult(in, a);
}

std::optional<model::DailyVerdict> ParseDailyVerdict(std::string_view name) {
  for (const model::DailyVerdict v : {model::DailyVerdict::kNoChange, model::DailyVerdict::kRefit,
                                      model::DailyVerdict::kRapidDue}) {
    if (model::DailyVerdictName(v) == name) return v;
  }
  return std::nullopt;
}

json DailyCheckOutcomeToJson(const DailyCheckOutcome& d) {
  json drifts = json::array();
  for (const DailyDrift& x : d.drifts) {
    drifts.push_back({{"name", x.name},
                      {"stored", FiniteOrNull(x.stored)},
                      {"today", FiniteOrNull(x.today)},
                      {"change", FiniteOrNull(x.change)},
                      {"bound", FiniteOrNull(x.bound)},
                      {"moved", x.moved}});
  }
  return {{"verdict", std::string(model::DailyVerdictName(d.verdict))},
          {"summary", d.summary},
          {"drifts", std::move(drifts)},
          {"refitted", d.refitted},
          {"recruitment_misfit", FiniteOrNull(d.recruitment_misfit)},
          {"history_sets", d.history_sets},
          {"compared_with", d.compared_with},
          {"base_parameter_set_id", OrNull(d.base_parameter_set_id)},
          {"swing_e_rms_deg",
           {{"stored", FiniteOrNull(d.swing_e_rms_stored_deg)},
            {"updated", FiniteOrNull(d.swing_e_rms_updated_deg)}}}};
}

namespace {

Result<DailyDrift> DailyDriftFromJson(const json& j) {
  JsonFields in(j);
  DailyDrift d;
  if (const auto name = in.String("name", true)) d.name = *name;
  ReadInto(in, "stored", d.stored);
  ReadInto(in, "today", d.today);
  ReadInto(in, "change", d.change);
  ReadInto(in, "bound", d.bound);
  ReadInto(in, "moved", d.moved);
  return ReadResult(in, std::move(d));
}

}  // namespace

Result<DailyCheckOutcome> DailyCheckOutcomeFromJson(const json& j) {
  JsonFields in(j);
  DailyCheckOutcome d;
  ReadNamed(in, "verdict", true, d.verdict, &ParseDailyVerdict);
  ReadInto(in, "summary", d.summary);
  if (const json* drifts = in.Any("drifts", false)) {
    if (!drifts->is_array()) in.Fail("drifts", "must be an array");
    for (std::size_t i = 0; in.ok() && drifts->is_array() && i < drifts->size(); ++i) {
      Result<DailyDrift> drift = DailyDriftFromJson((*drifts)[i]);
      if (!drift.ok()) {
        in.Fail("drifts[" + std::to_string(i) + "]." + drift.status().field(),
                drift.status().message());
      } else {
        d.drifts.push_back(*std::move(drift));
      }
    }
  }
  ReadInto(in, "refitted", d.refitted);
  ReadInto(in, "recruitment_misfit", d.recruitment_misfit);
  ReadInto(in, "history_sets", d.history_sets);
  ReadInto(in, "compared_with", d.compared_with);
  ReadInto(in, "base_parameter_set_id", d.base_parameter_set_id);
  if (const json* swing = in.Object("swing_e_rms_deg", false)) {
    JsonFields s(*swing, in.PathOf("swing_e_rms_deg"));
    ReadInto(s, "stored", d.swing_e_rms_stored_deg);
    ReadInto(s, "updated", d.swing_e_rms_updated_deg);
    if (!s.ok()) in.Fail("swing_e_rms_deg", s.status().message());
  }
  return ReadResult(in, std::move(d));
}

json RunOutcomeToJson(const RunOutcome& o) {
  json j = {{"state", std::string(RunStateName(o.state))},
            {"reason", o.reason},
            {"parameter_set_id", OrNull(o.parameter_set_id)},
            {"used_parameter_set_id", OrNull(o.used_parameter_set_id)},
            {"session_revision", OrNull(o.session_revision)}};
  if (o.tolerance) j["tolerance"] = ToleranceOutcomeToJson(*o.tolerance);
  if (o.amplitude_search) j["amplitude_search"] = AmplitudeSearchOutcomeToJson(*o.amplitude_search);
  if (o.daily_check) j["daily_check"] = DailyCheckOutcomeToJson(*o.daily_check);
  if (o.tracking) {
    json figures = json::object();
    for (const auto& [name, value] : o.tracking->figures) figures[name] = FiniteOrNull(value);
    j["tracking"] = std::move(figures);
  }
  return j;
}

Result<RunOutcome> RunOutcomeFromJson(const json& j) {
  JsonFields in(j);
  RunOutcome o;
  ReadNamed(in, "state", true, o.state, &ParseRunState);
  if (in.ok() && !IsFinal(o.state)) in.Fail("state", "must be done, failed or aborted");
  ReadInto(in, "reason", o.reason);
  ReadInto(in, "parameter_set_id", o.parameter_set_id);
  ReadInto(in, "used_parameter_set_id", o.used_parameter_set_id);
  ReadInto(in, "session_revision", o.session_revision);
  ReadNested(in, "tolerance", false, o.tolerance, &ToleranceOutcomeFromJson);
  ReadNested(in, "amplitude_search", false, o.amplitude_search, &AmplitudeSearchOutcomeFromJson);
  ReadNested(in, "daily_check", false, o.daily_check, &DailyCheckOutcomeFromJson);
  if (const json* figures = in.Object("tracking", false)) {
    JsonFields f(*figures, in.PathOf("tracking"));
    TrackingOutcome tracking;
    for (const auto& [name, value] : figures->items()) {
      // null: a figure that was not finite.
      tracking.figures[name] = std::nan("");
      ReadInto(f, name, tracking.figures[name]);
    }
    if (!f.ok()) in.Fail("tracking", f.status().message());
    o.tracking = std::move(tracking);
  }
  return ReadResult(in, std::move(o));
}

json RunResultJsonOf(const RunOutcome& o) {
  const bool done = o.state == RunState::kDone;
  if (done && o.tolerance) {
    const ToleranceOutcome& t = *o.tolerance;
    json r = {{"threshold_ma", OrNull(t.threshold_ma)},
              {"max_tolerated_ma", OrNull(t.max_tolerated_ma)},
              {"session_revision", OrNull(o.session_revision)}};
    if (t.subject_signalled_limit) r["subject_signalled_limit"] = *t.subject_signalled_limit;
    if (t.ended_at_ceiling) {
      r["ended_at_ceiling"] = true;
      r["message"] = t.message;
    }
    return r;
  }
  if (done && o.daily_check) {
    json r = DailyCheckOutcomeToJson(*o.daily_check);
    r["parameter_set_id"] = OrNull(o.parameter_set_id);
    return r;
  }
  if (o.parameter_set_id) return {{"parameter_set_id", *o.parameter_set_id}};
  return nullptr;
}

std::map<std::string, double> RunValuesOf(const RunOutcome& o) {
  std::map<std::string, double> values;
  if (o.tolerance && o.tolerance->subject_signalled_limit) {
    values["subject_signalled_limit"] = AsNumber(*o.tolerance->subject_signalled_limit);
  }
  if (o.amplitude_search) {
    const AmplitudeSearchOutcome& a = *o.amplitude_search;
    if (a.rb_amplitude_ma) values["rb_amplitude_ma"] = *a.rb_amplitude_ma;
    if (a.full_extension_amplitude_ma) {
      values["full_extension_amplitude_ma"] = *a.full_extension_amplitude_ma;
    }
    if (a.full_extension_reached) values["full_extension_reached"] = AsNumber(*a.full_extension_reached);
  }
  if (o.tracking) {
    for (const auto& [name, value] : o.tracking->figures) values[name] = value;
  }
  return values;
}

}  // namespace fesbench::api
