#pragma once

/// @file
/// A stored trial's metadata without samples (docs/API.md, "Trials": a
/// session's trials, the data listing). Storage lists trials as this type
/// (storage/trials.h). Readers as api/subject.h.

#include <cstddef>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "api/clock.h"
#include "api/status.h"
#include "api/trial_kind.h"

namespace fesbench::api {

struct TrialSummary {
  std::int64_t id = 0;
  std::int64_t session_id = 0;
  std::optional<std::int64_t> run_id;
  std::optional<std::string> name;
  std::optional<TrialKind> kind;  ///< none for a name of no kind.
  std::size_t num_samples = 0;    ///< per main channel.
  double sample_rate_hz = 0;
  UtcTime created_at;
  /// num_samples / sample_rate_hz, s (none without a rate).
  std::optional<double> duration_s() const;
  friend bool operator==(const TrialSummary&, const TrialSummary&) = default;
};
/// {"id", "session_id", "run_id", "name", "kind" (the protocol's trial name),
///  "num_samples", "sample_rate_hz", "duration_s", "created_at_utc"}; absent
/// values are null.
nlohmann::json TrialSummaryToJson(const TrialSummary& trial);
/// "duration_s" is derived, not read.
Result<TrialSummary> TrialSummaryFromJson(const nlohmann::json& json);

/// Where an imported trial came from: the "import" field of GET
/// /trials/{id} (docs/API.md, "Trials").
struct TrialImportRecord {
  std::string format;       ///< "csv", "tsv", "sto" or "archive".
  std::string source;       ///< what the importer said it is.
  nlohmann::json spec;      ///< the import spec (api/trial_import.h), or null.
  std::string imported_by;  ///< the user who imported it.
  std::optional<std::int64_t> original_trial_id;  ///< its id where it was exported from.
  friend bool operator==(const TrialImportRecord&, const TrialImportRecord&) = default;
};
/// {"format", "source", "spec", "imported_by", "original_trial_id"}.
nlohmann::json TrialImportRecordToJson(const TrialImportRecord& record);
Result<TrialImportRecord> TrialImportRecordFromJson(const nlohmann::json& json);
/// The "import" field of a trial's JSON form; none for a recorded trial.
Result<std::optional<TrialImportRecord>> TrialImportOf(const nlohmann::json& trial);

}  // namespace fesbench::api
