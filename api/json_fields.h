#pragma once

/// @file
/// Strict reading of JSON request bodies: every field checked for type and
/// range, unknown fields refused, and the first problem reported as
/// kInvalidArgument naming the field by its dotted path
/// ("details.height_cm", "trial_ids[2]").

#include <cstddef>
#include <cstdint>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "api/status.h"

namespace fesbench::api {

/// Deepest nesting of arrays and objects a request body may have.
inline constexpr int kMaxJsonDepth = 32;

/// Parses a request body. kInvalidArgument for an empty body, malformed
/// JSON (the message names the byte offset), nesting deeper than
/// kMaxJsonDepth, or a top level that is not an object.
Result<nlohmann::json> ParseJsonObject(std::string_view body);

/// Reads the fields of one JSON object. The first failure is kept (later
/// calls then return nullopt); Finish() adds the unknown-field check.
/// A JSON null counts as absent.
class JsonFields {
 public:
  /// `path` is the object's own dotted path ("" for the body).
  explicit JsonFields(const nlohmann::json& object, std::string path = {});

  std::optional<std::string> String(std::string_view key, bool required,
                                    std::size_t max_length = 1024);
  std::optional<double> Number(std::string_view key, bool required,
                               double min = -std::numeric_limits<double>::max(),
                               double max = std::numeric_limits<double>::max());
  std::optional<std::int64_t> Integer(std::string_view key, bool required,
                                      std::int64_t min = std::numeric_limits<std::int64_t>::min(),
                                      std::int64_t max = std::numeric_limits<std::int64_t>::max());
  std::optional<bool> Bool(std::string_view key, bool required);
  /// A positive integer id list (each ≥ 1), at most `max_items`.
  std::optional<std::vector<std::int64_t>> IdList(std::string_view key, bool required,
                                                  std::size_t max_items = 10000);
  /// The raw value if it is an object (nullptr when absent or on error).
  const nlohmann::json* Object(std::string_view key, bool required);
  /// The raw value, any type (nullptr when absent).
  const nlohmann::json* Any(std::string_view key, bool required);

  /// OK, or the first failure, or kInvalidArgument for the first field not
  /// read by any call above ("unknown field").
  Status Finish();
  bool ok() const { return status_.ok(); }
  const Status& status() const { return status_; }
  /// The dotted path of `key` in this object.
  std::string PathOf(std::string_view key) const;

 private:
  const nlohmann::json* Find(std::string_view key, bool required);
  void Fail(std::string_view key, std::string message);

  const nlohmann::json& object_;
  std::string path_;
  std::set<std::string, std::less<>> seen_;
  Status status_;
};

}  // namespace fesbench::api
