#pragma once

/// @file
/// The envelopes of answers (docs/API.md, "HTTP conventions"): a page of a
/// list ({"items", "next_cursor"}) and an error ({"error": {"code",
/// "message", "field"?}}, the object of api/job.h's ErrorToJson). The items of a page are read by the reader of
/// their own type (ItemsFromJson).

#include <cstddef>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "api/status.h"

namespace fesbench::api {

/// One page of a list; `next_cursor` names the next page (none: the last).
struct Page {
  std::vector<nlohmann::json> items;
  std::optional<std::string> next_cursor;
  friend bool operator==(const Page&, const Page&) = default;
};
/// {"items": [...], "next_cursor": "..." | null}.
nlohmann::json PageToJson(const Page& page);
/// "items" must be an array; a non-string cursor reads as the last page.
Result<Page> PageFromJson(const nlohmann::json& json);

/// Each item read by `from`; the first failure names its index ("items[2].id").
template <typename T>
Result<std::vector<T>> ItemsFromJson(const std::vector<nlohmann::json>& items,
                                     Result<T> (*from)(const nlohmann::json&)) {
  std::vector<T> out;
  out.reserve(items.size());
  for (std::size_t i = 0; i < items.size(); ++i) {
    Result<T> item = from(items[i]);
    if (!item.ok()) {
      const std::string& field = item.status().field();
      return Status::InvalidArgument(
          item.status().message(),
          "items[" + std::to_string(i) + "]" + (field.empty() ? "" : "." + field));
    }
    out.push_back(*std::move(item));
  }
  return out;
}

/// The error of an error answer's body {"error": {...}} (the object read
/// by ErrorFromJson, api/job.h); none when the body has no "error" object.
std::optional<Status> ErrorAnswerFromJson(const nlohmann::json& body);
/// {"error": ErrorToJson(status)}.
nlohmann::json ErrorAnswerToJson(const Status& status);

}  // namespace fesbench::api
