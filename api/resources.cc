#include "api/resources.h"

#include <string>
#include <utility>

#include "api/json_fields.h"
#include "api/parameter_set_json.h"

namespace fesbench::api {

namespace {

using nlohmann::json;

template <typename T>
Result<T> Done(const JsonFields& in, T value) {
  if (!in.ok()) return in.status();
  return value;
}

void ReadLegs(JsonFields& in, std::vector<LegRef>& legs) {
  const json* list = in.Any("legs", false);
  if (list == nullptr) return;
  if (!list->is_array()) {
    in.Fail("legs", "must be an array");
    return;
  }
  for (std::size_t i = 0; i < list->size(); ++i) {
    JsonFields item((*list)[i]);
    LegRef leg;
    leg.id = item.Integer("id", true).value_or(0);
    ReadInto(item, "side", leg.side);
    if (!item.ok()) {
      in.Fail("legs[" + std::to_string(i) + "]." + item.status().field(), item.status().message());
      return;
    }
    legs.push_back(std::move(leg));
  }
}

}  // namespace

Result<SubjectResource> SubjectResourceFromJson(const json& j) {
  JsonFields in(j);
  SubjectResource s;
  s.id = in.Integer("id", true).value_or(0);
  ReadInto(in, "code", s.code);
  ReadInto(in, "revision", s.revision);
  ReadLegs(in, s.legs);
  return Done(in, std::move(s));
}

Result<SessionResource> SessionResourceFromJson(const json& j) {
  JsonFields in(j);
  SessionResource s;
  s.id = in.Integer("id", true).value_or(0);
  ReadInto(in, "subject_id", s.subject_id);
  s.leg_id = in.Integer("leg_id", true).value_or(0);
  ReadInto(in, "leg", s.leg);
  ReadInto(in, "date", s.date);
  ReadInto(in, "revision", s.revision);
  return Done(in, std::move(s));
}

Result<TrialResource> TrialResourceFromJson(const json& j) {
  JsonFields in(j);
  TrialResource t;
  t.id = in.Integer("id", true).value_or(0);
  ReadInto(in, "session_id", t.session_id);
  ReadInto(in, "run_id", t.run_id);
  ReadInto(in, "name", t.name);
  TrialKind kind{};
  if (in.Any("kind", false) != nullptr) {
    ReadNamed(in, "kind", false, kind, &ParseTrialKind);
    if (in.ok()) t.kind = kind;
  }
  ReadInto(in, "num_samples", t.num_samples);
  ReadInto(in, "sample_rate_hz", t.sample_rate_hz);
  return Done(in, std::move(t));
}

Result<ParameterSetResource> ParameterSetResourceFromJson(const json& j) {
  JsonFields in(j);
  ParameterSetResource p;
  p.id = in.Integer("id", true).value_or(0);
  ReadInto(in, "subject_id", p.subject_id);
  ReadInto(in, "leg_id", p.leg_id);
  ReadInto(in, "version", p.version);
  ReadInto(in, "model", p.model);
  ReadInto(in, "trial_ids", p.trial_ids);
  if (const json* parameters = in.Any("parameters", false); parameters != nullptr && in.ok()) {
    Result<model::ParameterSet> set = ParameterSetFromJson(*parameters);
    if (set.ok()) {
      p.parameters = *std::move(set);
    } else {
      const std::string& field = set.status().field();
      in.Fail(field.empty() ? "parameters" : "parameters." + field, set.status().message());
    }
  }
  return Done(in, std::move(p));
}

}  // namespace fesbench::api
