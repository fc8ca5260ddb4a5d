#include "api/subject.h"

#include <utility>

#include "api/json_fields.h"
#include "api/json_read.h"
#include "api/name_table.h"
#include "api/time_utc.h"

namespace fesbench::api {
namespace {

using nlohmann::json;

constexpr NameTable<Sex, 4> kSexes({{{Sex::kFemale, "female"},
                                     {Sex::kMale, "male"},
                                     {Sex::kOther, "other"},
                                     {Sex::kUndisclosed, "undisclosed"}}},
                                   "undisclosed");

constexpr NameTable<Side, 2> kSides({{{Side::kLeft, "left"}, {Side::kRight, "right"}}}, "right");

template <typename T>
void PutOptional(json& j, const char* key, const std::optional<T>& value) {
  if (value) j[key] = *value;
}

Result<SubjectLeg> SubjectLegFromJson(const json& j) {
  JsonFields in(j);
  SubjectLeg leg;
  leg.id = in.Integer("id", true).value_or(0);
  ReadNamed(in, "side", true, leg.side, &ParseSide);
  return ReadResult(in, leg);
}

}  // namespace

std::string_view SexName(Sex sex) { return kSexes.Name(sex); }
std::optional<Sex> ParseSex(std::string_view name) { return kSexes.Parse(name); }
std::string_view SideName(Side side) { return kSides.Name(side); }
std::optional<Side> ParseSide(std::string_view name) { return kSides.Parse(name); }

json SubjectDetailsToJson(const SubjectDetails& d) {
  json j = json::object();
  PutOptional(j, "age_years", d.age_years);
  j["sex"] = SexName(d.sex);
  PutOptional(j, "height_cm", d.height_cm);
  PutOptional(j, "weight_kg", d.weight_kg);
  PutOptional(j, "shank_length_cm", d.shank_length_cm);
  PutOptional(j, "calf_circumference_cm", d.calf_circumference_cm);
  PutOptional(j, "rom_min_deg", d.rom_min_deg);
  PutOptional(j, "rom_max_deg", d.rom_max_deg);
  return j;
}

Result<SubjectDetails> SubjectDetailsFromJson(const json& j) {
  JsonFields in(j);
  SubjectDetails d;
  ReadInto(in, "age_years", d.age_years);
  ReadNamed(in, "sex", false, d.sex, &ParseSex);
  ReadInto(in, "height_cm", d.height_cm);
  ReadInto(in, "weight_kg", d.weight_kg);
  ReadInto(in, "shank_length_cm", d.shank_length_cm);
  ReadInto(in, "calf_circumference_cm", d.calf_circumference_cm);
  ReadInto(in, "rom_min_deg", d.rom_min_deg);
  ReadInto(in, "rom_max_deg", d.rom_max_deg);
  return ReadResult(in, d);
}

json SubjectToJson(const Subject& s) {
  json legs = json::array();
  for (const SubjectLeg& leg : s.legs)
    legs.push_back({{"id", leg.id}, {"side", SideName(leg.side)}});
  return {{"id", s.id},
          {"code", s.code},
          {"created_at_utc", FormatUtc(s.created_at)},
          {"revision", s.revision},
          {"details", SubjectDetailsToJson(s.details)},
          {"legs", std::move(legs)}};
}

Result<Subject> SubjectFromJson(const json& j) {
  JsonFields in(j);
  Subject s;
  s.id = in.Integer("id", true).value_or(0);
  ReadInto(in, "code", s.code);
  ReadTime(in, "created_at_utc", false, s.created_at);
  ReadInto(in, "revision", s.revision);
  ReadNested(in, "details", false, s.details, &SubjectDetailsFromJson);
  ReadList(in, "legs", false, s.legs, &SubjectLegFromJson);
  return ReadResult(in, std::move(s));
}

json SubjectRevisionToJson(const SubjectRevisionView& r) {
  return {{"revision", r.revision},
          {"corrects_revision", OrNull(r.corrects_revision)},
          {"reason", r.reason},
          {"changed_by", OrNull(r.changed_by)},
          {"changed_at_utc", FormatUtc(r.changed_at)},
          {"details", SubjectDetailsToJson(r.details)}};
}

Result<SubjectRevisionView> SubjectRevisionFromJson(const json& j) {
  JsonFields in(j);
  SubjectRevisionView r;
  r.revision = static_cast<int>(in.Integer("revision", true).value_or(0));
  ReadInto(in, "corrects_revision", r.corrects_revision);
  ReadInto(in, "reason", r.reason);
  ReadInto(in, "changed_by", r.changed_by);
  ReadTime(in, "changed_at_utc", false, r.changed_at);
  ReadNested(in, "details", false, r.details, &SubjectDetailsFromJson);
  return ReadResult(in, std::move(r));
}

json NewSubjectRequestToJson(const NewSubjectRequest& request) {
  json legs = json::array();
  for (Side side : request.legs) legs.push_back(SideName(side));
  json body = {{"code", request.code}, {"legs", std::move(legs)}};
  if (request.details != SubjectDetails{}) body["details"] = SubjectDetailsToJson(request.details);
  return body;
}

}  // namespace fesbench::api
