#pragma once

/// @file
/// The server's strict readers of the stored resources' request bodies
/// (docs/API.md; the shapes are api/subject.h, api/session.h, api/user.h),
/// and the fit notes of a set's resource. Readers refuse unknown fields,
/// wrong types and out-of-range values with kInvalidArgument naming the
/// field. The resources are written by the api/ writers.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "api/parameter_set_record.h"
#include "api/session.h"
#include "api/status.h"
#include "api/subject.h"
#include "api/user.h"
#include "storage/parameter_sets.h"
#include "storage/resources.h"
#include "storage/sessions.h"
#include "storage/subjects.h"

namespace fesbench::server::http {

/// The set's resource: storage's (storage/resources.h) with its fit warnings
/// in a clinician's words as "fit_notes" (services::ClinicalWarning).
api::StoredParameterSet ParameterSetResourceWithNotes(const storage::StoredParameterSet& set);

/// POST /subjects (api::NewSubjectRequest).
api::Result<api::NewSubjectRequest> NewSubjectFromJson(const nlohmann::json& body);
/// The details object at `path` (all fields optional; ranges as
/// storage::ValidateSubjectDetails).
api::Result<storage::SubjectDetails> SubjectDetailsRequestFromJson(const nlohmann::json& json,
                                                            const std::string& path);

/// POST /subjects/{id}/sessions (api::NewSessionRequest).
api::Result<api::NewSessionRequest> NewSessionFromJson(const nlohmann::json& body);

/// PATCH /subjects/{id} and /sessions/{id} (docs/API.md, "Corrections"): {"reason",
/// "details": {...}}. The given fields replace the current ones, null
/// clears one, the others are kept. `changed` lists the given fields.
struct SubjectCorrection {
  std::string reason;
  storage::SubjectDetails details;
  std::vector<std::string> changed;
};
struct SessionCorrection {
  std::string reason;
  storage::SessionDetails details;
  std::vector<std::string> changed;
};
/// kInvalidArgument naming the field ("reason", "details.weight_kg") with
/// the unit and allowed range in the message.
api::Result<SubjectCorrection> SubjectCorrectionFromJson(const nlohmann::json& body,
                                                         const storage::SubjectDetails& current);
api::Result<SessionCorrection> SessionCorrectionFromJson(const nlohmann::json& body,
                                                         const storage::SessionDetails& current);
/// POST /users (api::NewUserRequest).
api::Result<api::NewUserRequest> NewUserFromJson(const nlohmann::json& body);

/// POST /tokens (api::NewTokenRequest; expiry 60 s – 10 years).
api::Result<api::NewTokenRequest> NewTokenFromJson(const nlohmann::json& body);

}  // namespace fesbench::server::http
