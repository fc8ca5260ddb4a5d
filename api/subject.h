#pragma once

/// @file
/// A subject on the wire (docs/API.md, "Subjects"; docs/ARCHITECTURE.md,
/// storage): the pseudonymous code, the current anthropometrics, the legs
/// and the revisions of the details. Storage keeps the same details
/// (storage/subjects.h uses these types); the server writes the resources
/// with the writers here and the clients read them with the readers.
///
/// The readers (…FromJson) check the types of the fields they know and
/// ignore fields they do not; a missing or mistyped field they need is
/// kInvalidArgument naming it.

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/clock.h"
#include "api/status.h"

namespace fesbench::api {

enum class Sex { kFemale, kMale, kOther, kUndisclosed };
/// "female", "male", "other", "undisclosed".
std::string_view SexName(Sex sex);
std::optional<Sex> ParseSex(std::string_view name);

enum class Side { kLeft, kRight };
/// "left", "right".
std::string_view SideName(Side side);
std::optional<Side> ParseSide(std::string_view name);

/// Anthropometrics; absent values were not measured.
struct SubjectDetails {
  std::optional<int> age_years;  ///< 0–130.
  Sex sex = Sex::kUndisclosed;
  std::optional<double> height_cm;              ///< (30, 250].
  std::optional<double> weight_kg;              ///< (1, 400].
  std::optional<double> shank_length_cm;        ///< (10, 80].
  std::optional<double> calf_circumference_cm;  ///< (10, 100].
  /// The knee's range of motion, deg (flexion positive, 0 = full
  /// extension): from rom_min_deg (hyperextension negative, −30…60) to
  /// rom_max_deg (60…180), both or neither, at least 30° apart. On the bench
  /// it narrows the bench's range (the safety layer's limits, docs/SAFETY.md).
  std::optional<double> rom_min_deg;
  std::optional<double> rom_max_deg;
  friend bool operator==(const SubjectDetails&, const SubjectDetails&) = default;
};
/// {"age_years", "sex", "height_cm", "weight_kg", "shank_length_cm",
///  "calf_circumference_cm", "rom_min_deg", "rom_max_deg"} (unmeasured
/// values omitted).
nlohmann::json SubjectDetailsToJson(const SubjectDetails& details);
Result<SubjectDetails> SubjectDetailsFromJson(const nlohmann::json& json);

/// One of a subject's legs.
struct SubjectLeg {
  std::int64_t id = 0;
  Side side = Side::kRight;
  friend bool operator==(const SubjectLeg&, const SubjectLeg&) = default;
};

/// The subject resource (GET /subjects/{id}, the subjects list).
struct Subject {
  std::int64_t id = 0;
  std::string code;  ///< pseudonymous: [A-Za-z0-9_-], 1–32 characters.
  UtcTime created_at;
  int revision = 1;        ///< of the current details.
  SubjectDetails details;  ///< current.
  std::vector<SubjectLeg> legs;
  friend bool operator==(const Subject&, const Subject&) = default;
};
/// {"id", "code", "created_at_utc", "revision", "details": {...},
///  "legs": [{"id", "side"}]}.
nlohmann::json SubjectToJson(const Subject& subject);
Result<Subject> SubjectFromJson(const nlohmann::json& json);

/// One revision of a record's details (GET /subjects/{id}/revisions,
/// /sessions/{id}/revisions; docs/API.md, "Corrections"). `Details` is
/// SubjectDetails or SessionDetails (api/session.h).
template <typename Details>
struct Revision {
  int revision = 1;                      ///< 1 for the original, then 2, 3, …
  std::optional<int> corrects_revision;  ///< the revision it corrects (none for 1).
  std::string reason;
  std::optional<std::string> changed_by;  ///< user name, or unknown.
  UtcTime changed_at;
  Details details;
  friend bool operator==(const Revision&, const Revision&) = default;
};
using SubjectRevisionView = Revision<SubjectDetails>;
/// {"revision", "corrects_revision" (null for 1), "reason", "changed_by"
///  (user name or null), "changed_at_utc", "details"}.
nlohmann::json SubjectRevisionToJson(const SubjectRevisionView& revision);
Result<SubjectRevisionView> SubjectRevisionFromJson(const nlohmann::json& json);

/// PATCH of a record's details (docs/API.md, "Corrections"): {"reason",
/// "details": {...}} with the fields in `set` at their values in `details`
/// and the fields in `clear` as null (the server's strict reader is
/// server/http/resources_json.h).
template <typename Details>
struct CorrectionRequest {
  std::string reason;
  Details details;                 ///< the new values of the fields named in `set`.
  std::vector<std::string> set;    ///< wire names of the fields given a value.
  std::vector<std::string> clear;  ///< wire names of the fields cleared.
};
/// `details_to_json` writes the whole details object (SubjectDetailsToJson,
/// SessionDetailsToJson); a field of `set` it does not write is sent as null.
template <typename Details>
nlohmann::json CorrectionRequestToJson(const CorrectionRequest<Details>& request,
                                       nlohmann::json (*details_to_json)(const Details&)) {
  const nlohmann::json values = details_to_json(request.details);
  nlohmann::json details = nlohmann::json::object();
  for (const std::string& field : request.clear) details[field] = nullptr;
  for (const std::string& field : request.set) {
    const auto it = values.find(field);
    details[field] = it == values.end() ? nlohmann::json(nullptr) : *it;
  }
  return {{"reason", request.reason}, {"details", std::move(details)}};
}

/// POST /subjects: {"code", "details"?: {...}, "legs"?: ["left"|"right"]}
/// (the server's strict reader is server/http/resources_json.h).
struct NewSubjectRequest {
  std::string code;
  SubjectDetails details;
  std::vector<Side> legs;
};
/// "details" is written when a value in it is given.
nlohmann::json NewSubjectRequestToJson(const NewSubjectRequest& request);

}  // namespace fesbench::api
