#pragma once

/// @file
/// What an import stored (docs/API.md, POST /sessions/{id}/trials and the
/// session archive's import): the new trials and parameter sets with their
/// ids where they were exported from, and notes on what was left out.
/// Readers as api/subject.h.

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "api/status.h"

namespace fesbench::api {

struct ImportedItem {
  std::int64_t id = 0;
  std::optional<std::int64_t> original_id;  ///< its id in the exporting server.
  std::string name;
  friend bool operator==(const ImportedItem&, const ImportedItem&) = default;
};

struct ImportResult {
  std::vector<ImportedItem> trials;
  std::vector<ImportedItem> parameter_sets;
  std::vector<std::string> notes;  ///< what was left out and why.
  friend bool operator==(const ImportResult&, const ImportResult&) = default;
};
/// {"trials": [{"id", "name", "original_id"}], "parameter_sets": [...],
///  "notes": [...]}.
nlohmann::json ImportResultToJson(const ImportResult& result);
Result<ImportResult> ImportResultFromJson(const nlohmann::json& json);

}  // namespace fesbench::api
