#pragma once

/// @file
/// What a client reads of the stored resources (docs/API.md: `subjects`,
/// `sessions`, `trials`, `parameter-sets`): the fields the CLI and the study
/// act on, read from the server's answers. The server writes these shapes
/// (server/http/resources_json.h); a field a reader below does not name is
/// ignored, so a client keeps working against a newer server, and a missing
/// or mistyped field it needs is kInvalidArgument naming it.

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "api/status.h"
#include "api/trial_kind.h"
#include "model/parameter_set.h"

namespace fesbench::api {

/// One leg of a subject: {"id", "side"}.
struct LegRef {
  std::int64_t id = 0;
  std::string side;  ///< "left" or "right".
  friend bool operator==(const LegRef&, const LegRef&) = default;
};

/// A subject: {"id", "code", "revision", "legs": [{"id", "side"}], …}.
struct SubjectResource {
  std::int64_t id = 0;
  std::string code;
  int revision = 0;
  std::vector<LegRef> legs;
  friend bool operator==(const SubjectResource&, const SubjectResource&) = default;
};
/// Needs "id".
Result<SubjectResource> SubjectResourceFromJson(const nlohmann::json& json);

/// A session: {"id", "subject_id", "leg_id", "leg", "date", "revision", …}.
struct SessionResource {
  std::int64_t id = 0;
  std::int64_t subject_id = 0;
  std::int64_t leg_id = 0;
  std::string leg;   ///< "left" or "right".
  std::string date;  ///< ISO 8601 date.
  int revision = 0;
  friend bool operator==(const SessionResource&, const SessionResource&) = default;
};
/// Needs "id" and "leg_id".
Result<SessionResource> SessionResourceFromJson(const nlohmann::json& json);

/// A stored trial's summary: {"id", "session_id", "run_id", "name", "kind",
/// "num_samples", "sample_rate_hz", …}.
struct TrialResource {
  std::int64_t id = 0;
  std::int64_t session_id = 0;
  std::optional<std::int64_t> run_id;  ///< the run that recorded it; unset when imported.
  std::optional<std::string> name;
  std::optional<TrialKind> kind;  ///< the protocol's trial it is (api/trial_kind.h).
  std::int64_t num_samples = 0;
  double sample_rate_hz = 0.0;
  friend bool operator==(const TrialResource&, const TrialResource&) = default;
};
/// Needs "id"; a "kind" other than a trial kind's name is kInvalidArgument.
Result<TrialResource> TrialResourceFromJson(const nlohmann::json& json);

/// A stored parameter set: {"id", "subject_id", "leg_id", "version",
/// "model", "trial_ids", "parameters" (docs/MODEL.md), …}.
struct ParameterSetResource {
  std::int64_t id = 0;
  std::int64_t subject_id = 0;
  std::int64_t leg_id = 0;
  int version = 0;
  std::string model;
  std::vector<std::int64_t> trial_ids;  ///< the trials it was fitted on.
  /// The set itself (GET /parameter-sets/{id}; the lists omit it).
  std::optional<model::ParameterSet> parameters;
  friend bool operator==(const ParameterSetResource&, const ParameterSetResource&) = default;
};
/// Needs "id"; "parameters", when present, is read by ParameterSetFromJson
/// (its errors named "parameters.…").
Result<ParameterSetResource> ParameterSetResourceFromJson(const nlohmann::json& json);

}  // namespace fesbench::api
