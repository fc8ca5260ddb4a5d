#include "server/http/resources_json.h"

#include <cmath>
#include <sstream>

#include "api/json_fields.h"
#include "server/services/model_check.h"
#include "api/time_utc.h"
#include "storage/resources.h"

namespace fesbench::server::http {

api::StoredParameterSet ParameterSetResourceWithNotes(const storage::StoredParameterSet& set) {
  api::StoredParameterSet resource = storage::StoredParameterSetResource(set);
  for (const std::string& w : set.params.provenance.warnings) {
    resource.fit_notes.push_back(services::ClinicalWarning(w));
  }
  return resource;
}

api::Result<storage::SubjectDetails> SubjectDetailsRequestFromJson(const nlohmann::json& json,
                                                            const std::string& path) {
  api::JsonFields f(json, path);
  storage::SubjectDetails d;
  if (auto age = f.Integer("age_years", false, 0, 130)) d.age_years = static_cast<int>(*age);
  if (auto sex = f.String("sex", false, 32)) {
    auto parsed = storage::ParseSex(*sex);
    if (!parsed) {
      return api::Status::InvalidArgument("must be female, male, other or undisclosed",
                                          f.PathOf("sex"));
    }
    d.sex = *parsed;
  }
  d.height_cm = f.Number("height_cm", false, 30.0, 250.0);
  d.weight_kg = f.Number("weight_kg", false, 1.0, 400.0);
  d.shank_length_cm = f.Number("shank_length_cm", false, 10.0, 80.0);
  d.calf_circumference_cm = f.Number("calf_circumference_cm", false, 10.0, 100.0);
  d.rom_min_deg = f.Number("rom_min_deg", false, -30.0, 60.0);
  d.rom_max_deg = f.Number("rom_max_deg", false, 60.0, 180.0);
  if (auto st = f.Finish(); !st.ok()) return st;
  if (auto st = storage::ValidateSubjectDetails(d); !st.ok()) {
    return api::Status(st.code(), st.message(),
                       path.empty() ? st.field() : path + "." + st.field());
  }
  return d;
}

api::Result<api::NewSubjectRequest> NewSubjectFromJson(const nlohmann::json& body) {
  api::JsonFields f(body);
  api::NewSubjectRequest out;
  if (auto code = f.String("code", true, 32)) out.code = *code;
  if (const auto* details = f.Object("details", false)) {
    auto d = SubjectDetailsRequestFromJson(*details, "details");
    if (!d.ok()) return d.status();
    out.details = *d;
  }
  if (const auto* legs = f.Any("legs", false)) {
    if (!legs->is_array() || legs->size() > 2) {
      return api::Status::InvalidArgument("must be an array of at most two of left, right", "legs");
    }
    for (std::size_t i = 0; i < legs->size(); ++i) {
      const auto& item = (*legs)[i];
      auto side = item.is_string() ? storage::ParseSide(item.get<std::string>()) : std::nullopt;
      if (!side) {
        return api::Status::InvalidArgument("must be left or right",
                                            "legs[" + std::to_string(i) + "]");
      }
      if (std::find(out.legs.begin(), out.legs.end(), *side) != out.legs.end()) {
        return api::Status::InvalidArgument("duplicate leg", "legs[" + std::to_string(i) + "]");
      }
      out.legs.push_back(*side);
    }
  }
  if (auto st = f.Finish(); !st.ok()) return st;
  if (auto st = storage::ValidateSubjectCode(out.code); !st.ok()) return st;
  return out;
}

api::Result<api::NewSessionRequest> NewSessionFromJson(const nlohmann::json& body) {
  api::JsonFields f(body);
  api::NewSessionRequest out;
  if (auto leg = f.String("leg", true, 16)) {
    auto side = storage::ParseSide(*leg);
    if (!side) return api::Status::InvalidArgument("must be left or right", "leg");
    out.leg = *side;
  }
  if (auto date = f.String("date", true, 10)) out.details.date = *date;
  if (auto placement = f.String("accelerometer_placement", false, 256)) {
    out.details.accelerometer_placement = *placement;
  }
  out.details.threshold_ma = f.Number("threshold_ma", false, 0.0, 100.0);
  out.details.max_tolerated_ma = f.Number("max_tolerated_ma", false, 0.0, 100.0);
  if (auto notes = f.String("notes", false, 4096)) out.details.notes = *notes;
  if (auto st = f.Finish(); !st.ok()) return st;
  if (!api::IsIsoDate(out.details.date)) {
    return api::Status::InvalidArgument("must be a date YYYY-MM-DD", "date");
  }
  if (auto st = storage::ValidateSessionDetails(out.details); !st.ok()) return st;
  return out;
}

namespace {

constexpr std::size_t kMaxReasonLength = 500;

std::string FormatBound(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

// The correction's envelope: {"reason", "details"}; the reason is required.
api::Result<std::pair<std::string, const nlohmann::json*>> CorrectionEnvelope(
    const nlohmann::json& body) {
  api::JsonFields f(body);
  std::optional<std::string> reason = f.String("reason", true, 100000);
  const nlohmann::json* details = f.Object("details", true);
  if (auto st = f.Finish(); !st.ok()) return st;
  if (reason->find_first_not_of(" \t\r\n") == std::string::npos) {
    return api::Status::InvalidArgument("must say why the record is corrected (not empty)",
                                        "reason");
  }
  if (reason->size() > kMaxReasonLength) {
    return api::Status::InvalidArgument(
        "must be at most " + std::to_string(kMaxReasonLength) + " characters", "reason");
  }
  return std::make_pair(*reason, details);
}

// A number with unit in (low, high] (or [low, high] when `low_inclusive`);
// null clears it.
api::Status PatchNumber(const nlohmann::json& value, const std::string& field, const char* unit,
                        double low, double high, bool low_inclusive, std::optional<double>& out) {
  if (value.is_null()) {
    out.reset();
    return api::Status::Ok();
  }
  const std::string range = std::string(low_inclusive ? "[" : "(") + FormatBound(low) + ", " +
                            FormatBound(high) + "] " + unit;
  if (!value.is_number()) {
    return api::Status::InvalidArgument("must be a number in " + range + " (or null to clear it)",
                                        field);
  }
  const double v = value.get<double>();
  if (!std::isfinite(v) || (low_inclusive ? v < low : v <= low) || v > high) {
    return api::Status::InvalidArgument(
        "must be in " + range + ", got " + value.dump() + " " + unit, field);
  }
  out = v;
  return api::Status::Ok();
}

api::Status PatchText(const nlohmann::json& value, const std::string& field, std::size_t max_length,
                      std::string& out) {
  if (value.is_null()) {
    out.clear();
    return api::Status::Ok();
  }
  if (!value.is_string()) {
    return api::Status::InvalidArgument("must be text (or null to clear it)", field);
  }
  const auto& text = value.get_ref<const std::string&>();
  if (text.size() > max_length) {
    return api::Status::InvalidArgument(
        "must be at most " + std::to_string(max_length) + " characters", field);
  }
  out = text;
  return api::Status::Ok();
}

}  // namespace

api::Result<SubjectCorrection> SubjectCorrectionFromJson(const nlohmann::json& body,
                                                         const storage::SubjectDetails& current) {
  auto envelope = CorrectionEnvelope(body);
  if (!envelope.ok()) return envelope.status();
  SubjectCorrection out;
  out.reason = envelope->first;
  out.details = current;
  storage::SubjectDetails& d = out.details;
  for (const auto& [key, value] : envelope->second->items()) {
    const std::string field = "details." + key;
    api::Status st;
    if (key == "age_years") {
      if (value.is_null()) {
        d.age_years.reset();
      } else if (!value.is_number_integer() || value.get<std::int64_t>() < 0 ||
                 value.get<std::int64_t>() > 130) {
        st = api::Status::InvalidArgument(
            "must be a whole number of years in [0, 130], got " + value.dump(), field);
      } else {
        d.age_years = static_cast<int>(value.get<std::int64_t>());
      }
    } else if (key == "sex") {
      if (value.is_null()) {
        d.sex = storage::Sex::kUndisclosed;
      } else {
        auto sex = value.is_string() ? storage::ParseSex(value.get<std::string>()) : std::nullopt;
        if (!sex) {
          st = api::Status::InvalidArgument("must be female, male, other or undisclosed", field);
        } else {
          d.sex = *sex;
        }
      }
    } else if (key == "height_cm") {
      st = PatchNumber(value, field, "cm", 30, 250, false, d.height_cm);
    } else if (key == "weight_kg") {
      st = PatchNumber(value, field, "kg", 1, 400, false, d.weight_kg);
    } else if (key == "shank_length_cm") {
      st = PatchNumber(value, field, "cm", 10, 80, false, d.shank_length_cm);
    } else if (key == "calf_circumference_cm") {
      st = PatchNumber(value, field, "cm", 10, 100, false, d.calf_circumference_cm);
    } else if (key == "rom_min_deg") {
      st = PatchNumber(value, field, "deg", -30, 60, true, d.rom_min_deg);
    } else if (key == "rom_max_deg") {
      st = PatchNumber(value, field, "deg", 60, 180, true, d.rom_max_deg);
    } else {
      st = api::Status::InvalidArgument(
          "unknown field (allowed: age_years, sex, height_cm, weight_kg, shank_length_cm, "
          "calf_circumference_cm, rom_min_deg, rom_max_deg)",
          field);
    }
    if (!st.ok()) return st;
    out.changed.push_back(key);
  }
  if (out.changed.empty()) {
    return api::Status::InvalidArgument("must name at least one field to correct", "details");
  }
  if (auto st = storage::ValidateSubjectDetails(d); !st.ok()) {
    return api::Status(st.code(), st.message(), "details." + st.field());
  }
  return out;
}

api::Result<SessionCorrection> SessionCorrectionFromJson(const nlohmann::json& body,
                                                         const storage::SessionDetails& current) {
  auto envelope = CorrectionEnvelope(body);
  if (!envelope.ok()) return envelope.status();
  SessionCorrection out;
  out.reason = envelope->first;
  out.details = current;
  storage::SessionDetails& d = out.details;
  for (const auto& [key, value] : envelope->second->items()) {
    const std::string field = "details." + key;
    api::Status st;
    if (key == "date") {
      if (!value.is_string() || !api::IsIsoDate(value.get<std::string>())) {
        st = api::Status::InvalidArgument(
            "must be a calendar date YYYY-MM-DD (it cannot be cleared)", field);
      } else {
        d.date = value.get<std::string>();
      }
    } else if (key == "accelerometer_placement") {
      st = PatchText(value, field, 256, d.accelerometer_placement);
    } else if (key == "threshold_ma") {
      st = PatchNumber(value, field, "mA", 0, 100, true, d.threshold_ma);
    } else if (key == "max_tolerated_ma") {
      st = PatchNumber(value, field, "mA", 0, 100, true, d.max_tolerated_ma);
    } else if (key == "notes") {
      st = PatchText(value, field, 4096, d.notes);
    } else {
      st = api::Status::InvalidArgument(
          "unknown field (allowed: date, accelerometer_placement, threshold_ma, "
          "max_tolerated_ma, notes)",
          field);
    }
    if (!st.ok()) return st;
    out.changed.push_back(key);
  }
  if (out.changed.empty()) {
    return api::Status::InvalidArgument("must name at least one field to correct", "details");
  }
  if (d.threshold_ma && d.max_tolerated_ma && *d.threshold_ma > *d.max_tolerated_ma) {
    return api::Status::InvalidArgument(
        "the max tolerated amplitude (" + FormatBound(*d.max_tolerated_ma) +
            " mA) must not be below the threshold (" + FormatBound(*d.threshold_ma) + " mA)",
        "details.max_tolerated_ma");
  }
  if (auto st = storage::ValidateSessionDetails(d); !st.ok()) {
    return api::Status(st.code(), st.message(), "details." + st.field());
  }
  return out;
}

api::Result<api::NewUserRequest> NewUserFromJson(const nlohmann::json& body) {
  api::JsonFields f(body);
  api::NewUserRequest out;
  if (auto name = f.String("name", true, 64)) out.name = *name;
  if (auto role = f.String("role", true, 16)) {
    auto parsed = storage::ParseRole(*role);
    if (!parsed) return api::Status::InvalidArgument("must be clinician, analyst or admin", "role");
    out.role = *parsed;
  }
  if (auto st = f.Finish(); !st.ok()) return st;
  if (out.name.empty()) return api::Status::InvalidArgument("must not be empty", "name");
  return out;
}

api::Result<api::NewTokenRequest> NewTokenFromJson(const nlohmann::json& body) {
  api::JsonFields f(body);
  api::NewTokenRequest out;
  if (auto id = f.Integer("user_id", true, 1)) out.user_id = *id;
  if (auto label = f.String("label", false, 128)) out.label = *label;
  out.expires_in_s = f.Integer("expires_in_s", false, 60, 10LL * 365 * 24 * 3600);
  if (auto st = f.Finish(); !st.ok()) return st;
  return out;
}

}  // namespace fesbench::server::http
