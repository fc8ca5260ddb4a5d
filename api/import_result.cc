#include "api/import_result.h"

#include <utility>

#include "api/json_fields.h"
#include "api/json_read.h"

namespace fesbench::api {
namespace {

using nlohmann::json;

json ItemsToJson(const std::vector<ImportedItem>& items) {
  json out = json::array();
  for (const ImportedItem& item : items) {
    out.push_back(
        {{"id", item.id}, {"name", item.name}, {"original_id", OrNull(item.original_id)}});
  }
  return out;
}

Result<ImportedItem> ImportedItemFromJson(const json& j) {
  JsonFields in(j);
  ImportedItem item;
  item.id = in.Integer("id", true).value_or(0);
  ReadInto(in, "original_id", item.original_id);
  ReadInto(in, "name", item.name);
  return ReadResult(in, std::move(item));
}

}  // namespace

json ImportResultToJson(const ImportResult& result) {
  return {{"trials", ItemsToJson(result.trials)},
          {"parameter_sets", ItemsToJson(result.parameter_sets)},
          {"notes", result.notes}};
}

Result<ImportResult> ImportResultFromJson(const json& j) {
  JsonFields in(j);
  ImportResult result;
  ReadList(in, "trials", false, result.trials, &ImportedItemFromJson);
  ReadList(in, "parameter_sets", false, result.parameter_sets, &ImportedItemFromJson);
  ReadInto(in, "notes", result.notes);
  return ReadResult(in, std::move(result));
}

}  // namespace fesbench::api
