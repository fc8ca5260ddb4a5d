#pragma once

/// @file
/// A session on the wire (docs/API.md, "Sessions"): one leg of a subject
/// on one date, with the values the protocols are scaled to, and the
/// revisions of those details. Storage keeps the same details
/// (storage/sessions.h uses SessionDetails). Readers as api/subject.h.

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "api/clock.h"
#include "api/status.h"
#include "api/subject.h"

namespace fesbench::api {

struct SessionDetails {
  std::string date;                        ///< "YYYY-MM-DD" (local calendar date).
  std::string accelerometer_placement;     ///< e.g. "shank, 20 cm below knee".
  std::optional<double> threshold_ma;      ///< stimulation threshold, [0, 100] mA.
  std::optional<double> max_tolerated_ma;  ///< [threshold, 100] mA.
  std::string notes;
  friend bool operator==(const SessionDetails&, const SessionDetails&) = default;
};
/// {"date", "accelerometer_placement", "notes", "threshold_ma",
///  "max_tolerated_ma"} (unmeasured amplitudes omitted).
nlohmann::json SessionDetailsToJson(const SessionDetails& details);
Result<SessionDetails> SessionDetailsFromJson(const nlohmann::json& json);

/// The session resource (GET /sessions/{id}, a subject's sessions).
struct Session {
  std::int64_t id = 0;
  std::int64_t subject_id = 0;
  std::int64_t leg_id = 0;
  Side leg = Side::kRight;
  UtcTime created_at;
  int revision = 1;        ///< of the current details.
  SessionDetails details;  ///< current; its date is also the session's "date".
  friend bool operator==(const Session&, const Session&) = default;
};
/// {"id", "date", "subject_id", "leg_id", "leg", "created_at_utc",
///  "revision", "details": {...}}.
nlohmann::json SessionToJson(const Session& session);
Result<Session> SessionFromJson(const nlohmann::json& json);

using SessionRevisionView = Revision<SessionDetails>;
/// As SubjectRevisionToJson, with the session's details.
nlohmann::json SessionRevisionToJson(const SessionRevisionView& revision);
Result<SessionRevisionView> SessionRevisionFromJson(const nlohmann::json& json);

/// POST /subjects/{id}/sessions: {"leg", "date", "accelerometer_placement"?,
/// "threshold_ma"?, "max_tolerated_ma"?, "notes"?} (the server's strict
/// reader is server/http/resources_json.h).
struct NewSessionRequest {
  Side leg = Side::kRight;
  SessionDetails details;
};
/// Empty placement and notes are not written.
nlohmann::json NewSessionRequestToJson(const NewSessionRequest& request);

}  // namespace fesbench::api
