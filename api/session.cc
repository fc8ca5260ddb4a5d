#include "api/session.h"

#include <utility>

#include "api/json_fields.h"
#include "api/json_read.h"
#include "api/time_utc.h"

namespace fesbench::api {
namespace {

using nlohmann::json;

template <typename T>
void PutOptional(json& j, const char* key, const std::optional<T>& value) {
  if (value) j[key] = *value;
}

}  // namespace

json SessionDetailsToJson(const SessionDetails& d) {
  json j = {
      {"date", d.date}, {"accelerometer_placement", d.accelerometer_placement}, {"notes", d.notes}};
  PutOptional(j, "threshold_ma", d.threshold_ma);
  PutOptional(j, "max_tolerated_ma", d.max_tolerated_ma);
  return j;
}

Result<SessionDetails> SessionDetailsFromJson(const json& j) {
  JsonFields in(j);
  SessionDetails d;
  ReadInto(in, "date", d.date);
  ReadInto(in, "accelerometer_placement", d.accelerometer_placement);
  ReadInto(in, "threshold_ma", d.threshold_ma);
  ReadInto(in, "max_tolerated_ma", d.max_tolerated_ma);
  ReadInto(in, "notes", d.notes);
  return ReadResult(in, std::move(d));
}

json SessionToJson(const Session& s) {
  return {{"id", s.id},
          {"subject_id", s.subject_id},
          {"leg_id", s.leg_id},
          {"leg", SideName(s.leg)},
          {"date", s.details.date},
          {"created_at_utc", FormatUtc(s.created_at)},
          {"revision", s.revision},
          {"details", SessionDetailsToJson(s.details)}};
}

Result<Session> SessionFromJson(const json& j) {
  JsonFields in(j);
  Session s;
  s.id = in.Integer("id", true).value_or(0);
  ReadInto(in, "subject_id", s.subject_id);
  ReadInto(in, "leg_id", s.leg_id);
  ReadNamed(in, "leg", false, s.leg, &ParseSide);
  ReadTime(in, "created_at_utc", false, s.created_at);
  ReadInto(in, "revision", s.revision);
  ReadNested(in, "details", false, s.details, &SessionDetailsFromJson);
  if (s.details.date.empty()) ReadInto(in, "date", s.details.date);
  in.Any("date", false);
  return ReadResult(in, std::move(s));
}

json SessionRevisionToJson(const SessionRevisionView& r) {
  return {{"revision", r.revision},
          {"corrects_revision", OrNull(r.corrects_revision)},
          {"reason", r.reason},
          {"changed_by", OrNull(r.changed_by)},
          {"changed_at_utc", FormatUtc(r.changed_at)},
          {"details", SessionDetailsToJson(r.details)}};
}

Result<SessionRevisionView> SessionRevisionFromJson(const json& j) {
  JsonFields in(j);
  SessionRevisionView r;
  r.revision = static_cast<int>(in.Integer("revision", true).value_or(0));
  ReadInto(in, "corrects_revision", r.corrects_revision);
  ReadInto(in, "reason", r.reason);
  ReadInto(in, "changed_by", r.changed_by);
  ReadTime(in, "changed_at_utc", false, r.changed_at);
  ReadNested(in, "details", false, r.details, &SessionDetailsFromJson);
  return ReadResult(in, std::move(r));
}

json NewSessionRequestToJson(const NewSessionRequest& request) {
  const SessionDetails& d = request.details;
  json body = {{"leg", SideName(request.leg)}, {"date", d.date}};
  PutOptional(body, "threshold_ma", d.threshold_ma);
  PutOptional(body, "max_tolerated_ma", d.max_tolerated_ma);
  if (!d.notes.empty()) body["notes"] = d.notes;
  if (!d.accelerometer_placement.empty())
    body["accelerometer_placement"] = d.accelerometer_placement;
  return body;
}

}  // namespace fesbench::api
