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
#include <type_traits>
#include <vector>

#include "api/status.h"

namespace fesbench::api {

/// Deepest nesting of arrays and objects a request body may have.
inline constexpr int kMaxJsonDepth = 32;

/// What ParseJsonObject accepts beyond well-formed JSON.
struct JsonLimits {
  /// Most values (objects, arrays, strings, numbers, literals) in the text:
  /// a parsed document costs up to ~16 bytes of memory per byte of text
  /// ("[0,0,...]"), so a reader that expects few values says so.
  std::size_t max_values = std::numeric_limits<std::size_t>::max();
};

/// Parses client JSON (request bodies, uploaded files). kInvalidArgument
/// for an empty body, malformed JSON (the message names the byte offset),
/// nesting deeper than kMaxJsonDepth, an object with the same key twice
/// (the field names its path: "spec.columns[0].unit"; JSON leaves which
/// one counts to the reader, so neither does), more values than
/// `limits.max_values`, or a top level that is not an object.
Result<nlohmann::json> ParseJsonObject(std::string_view body, const JsonLimits& limits = {});

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
  /// Records a failure of `key` found by the caller's own check (kept only
  /// if it is the first).
  void Fail(std::string_view key, std::string message);

 private:
  const nlohmann::json* Find(std::string_view key, bool required);

  const nlohmann::json& object_;
  std::string path_;
  std::set<std::string, std::less<>> seen_;
  Status status_;
};

/// OK when `text` is printable text a person wrote: no control characters
/// (U+0000–U+001F, U+007F, U+0080–U+009F), and something besides spaces.
/// Otherwise kInvalidArgument naming `field`: "must be printable text: …".
Status CheckPrintableText(std::string_view text, std::string_view field);

/// An unset value as JSON null, a set one as itself (writers' counterpart
/// of the readers below).
template <typename T>
nlohmann::json OrNull(const std::optional<T>& value) {
  return value ? nlohmann::json(*value) : nlohmann::json(nullptr);
}

/// Lenient reading, for clients of a server that may send more than they
/// know: ReadInto stores a present, well-typed value of `key` in `out` and
/// leaves `out` as it is when the field is absent or null; a value of the
/// wrong type is the reader's failure. Finish() is not called, so unknown
/// fields pass.
void ReadInto(JsonFields& in, std::string_view key, double& out);
void ReadInto(JsonFields& in, std::string_view key, bool& out);
void ReadInto(JsonFields& in, std::string_view key, std::string& out);
void ReadInto(JsonFields& in, std::string_view key, std::optional<double>& out);
void ReadInto(JsonFields& in, std::string_view key, std::optional<std::string>& out);
void ReadInto(JsonFields& in, std::string_view key, std::vector<double>& out);
void ReadInto(JsonFields& in, std::string_view key, std::vector<std::string>& out);
void ReadInto(JsonFields& in, std::string_view key, std::vector<std::int64_t>& out);
template <typename Int>
  requires(std::is_integral_v<Int> && !std::is_same_v<Int, bool>)
void ReadInto(JsonFields& in, std::string_view key, Int& out) {
  if (const auto v = in.Integer(key, false)) out = static_cast<Int>(*v);
}
template <typename Int>
  requires(std::is_integral_v<Int> && !std::is_same_v<Int, bool>)
void ReadInto(JsonFields& in, std::string_view key, std::optional<Int>& out) {
  if (const auto v = in.Integer(key, false)) out = static_cast<Int>(*v);
}
/// A name read with `parse` ("kind": "estop" → SafetyEvent::Kind::kEStop);
/// a name `parse` does not know is a failure.
template <typename Enum>
void ReadNamed(JsonFields& in, std::string_view key, bool required, Enum& out,
               std::optional<Enum> (*parse)(std::string_view)) {
  if (const auto name = in.String(key, required)) {
    if (const std::optional<Enum> parsed = parse(*name)) {
      out = *parsed;
    } else {
      in.Fail(key, "unknown value \"" + name->substr(0, 40) + "\"");
    }
  }
}

}  // namespace fesbench::api
