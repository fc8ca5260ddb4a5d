#pragma once

/// @file
/// Helpers of the lenient readers of api/ (…FromJson of response shapes):
/// a time field, a nested object, a list of nested objects and the reader's
/// result. A nested failure is named by its path ("legs[1].side").

#include <cstddef>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "api/clock.h"
#include "api/json_fields.h"
#include "api/status.h"
#include "api/time_utc.h"

namespace fesbench::api {

/// A time field: ISO-8601 UTC text or null (absent).
inline void ReadTime(JsonFields& in, std::string_view key, std::optional<UtcTime>& out) {
  if (const auto text = in.String(key, false)) {
    out = ParseUtc(*text);
    if (!out) in.Fail(key, "must be an ISO-8601 UTC time, got \"" + text->substr(0, 40) + "\"");
  }
}
/// A time field the reader needs (`required`) or keeps as it is when absent.
inline void ReadTime(JsonFields& in, std::string_view key, bool required, UtcTime& out) {
  if (required) in.Any(key, true);
  std::optional<UtcTime> read;
  ReadTime(in, key, read);
  if (read) out = *read;
}

/// Fails `in` at `key` + the nested field of `status`.
inline void FailNested(JsonFields& in, const std::string& key, const Status& status) {
  const std::string& field = status.field();
  in.Fail(field.empty() ? key : key + "." + field, status.message());
}

/// A nested object read by `from` (absent or null: `out` kept).
template <typename T>
void ReadNested(JsonFields& in, std::string_view key, bool required, T& out,
                Result<T> (*from)(const nlohmann::json&)) {
  const nlohmann::json* object = in.Any(key, required);
  if (object == nullptr) return;
  Result<T> read = from(*object);
  if (read.ok()) {
    out = *std::move(read);
  } else {
    FailNested(in, std::string(key), read.status());
  }
}
template <typename T>
void ReadNested(JsonFields& in, std::string_view key, bool required, std::optional<T>& out,
                Result<T> (*from)(const nlohmann::json&)) {
  T value{};
  const bool present = in.Any(key, required) != nullptr;
  ReadNested(in, key, required, value, from);
  if (present && in.ok()) out = std::move(value);
}

/// An array of objects, each read by `from` (absent or null: `out` kept).
template <typename T>
void ReadList(JsonFields& in, std::string_view key, bool required, std::vector<T>& out,
              Result<T> (*from)(const nlohmann::json&)) {
  const nlohmann::json* list = in.Any(key, required);
  if (list == nullptr) return;
  if (!list->is_array()) {
    in.Fail(key, "must be an array");
    return;
  }
  std::vector<T> read;
  for (std::size_t i = 0; i < list->size(); ++i) {
    Result<T> item = from((*list)[i]);
    if (!item.ok()) {
      FailNested(in, std::string(key) + "[" + std::to_string(i) + "]", item.status());
      return;
    }
    read.push_back(*std::move(item));
  }
  out = std::move(read);
}

/// The reader's value, or its first failure.
template <typename T>
Result<T> ReadResult(const JsonFields& in, T value) {
  if (!in.ok()) return in.status();
  return value;
}

}  // namespace fesbench::api
