#include "api/json_fields.h"

#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace fesbench::api {

namespace {

// Nesting depth of a JSON text, ignoring brackets inside strings; stops
// early once `limit` is exceeded. Checked before parsing so that a deeply
// nested body never reaches recursive code.
int NestingDepth(std::string_view text, int limit) {
  int depth = 0, deepest = 0;
  bool in_string = false, escaped = false;
  for (char c : text) {
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      deepest = std::max(deepest, ++depth);
      if (deepest > limit) return deepest;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return deepest;
}

std::string TypeName(const nlohmann::json& j) { return j.type_name(); }

// A refusal found while parsing, thrown out of the parser callback.
struct ParseRefusal {
  std::string message;
  std::string path;
};

// The dotted path of the value being parsed, kept up to date by the parser
// callback, so that an error inside a value (a number beyond double range:
// 1e400) can name its field; it also refuses a key its object already has
// and a text with more values than allowed.
class PathTracker {
 public:
  explicit PathTracker(std::size_t max_values) : max_values_(max_values) {}

  bool operator()(int, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
    using Event = nlohmann::json::parse_event_t;
    switch (event) {
      case Event::object_start:
      case Event::array_start:
        CountValue();
        frames_.push_back({event == Event::array_start, {}, 0, {}});
        break;
      case Event::object_end:
      case Event::array_end:
        if (!frames_.empty()) frames_.pop_back();
        if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
        break;
      case Event::key:
        if (!frames_.empty() && parsed.is_string()) Key(parsed.get<std::string>());
        break;
      case Event::value:
        CountValue();
        if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
        break;
    }
    return true;
  }
  std::string Path() const {
    std::string path;
    for (const auto& f : frames_) {
      if (f.array) {
        path += "[" + std::to_string(f.index) + "]";
      } else if (!f.key.empty()) {
        path += (path.empty() ? "" : ".") + f.key;
      }
    }
    return path;
  }

 private:
  struct Frame {
    bool array;
    std::string key;
    std::size_t index;
    std::set<std::string, std::less<>> keys;  // an object's keys so far.
  };

  void Key(std::string key) {
    Frame& frame = frames_.back();
    frame.key = key;
    if (!frame.keys.insert(std::move(key)).second) {
      throw ParseRefusal{"duplicate key: the object already has this field", Path()};
    }
  }
  void CountValue() {
    if (++values_ > max_values_) {
      throw ParseRefusal{"more than " + std::to_string(max_values_) + " JSON values", Path()};
    }
  }

  std::size_t max_values_;
  std::size_t values_ = 0;
  std::vector<Frame> frames_;
};
// The unit a field name carries as its suffix (docs/ARCHITECTURE.md, units: `weight_kg`,
// `threshold_ma`, `max_stop_impact_deg_s`), "" if none.
std::string UnitOf(std::string_view key) {
  static constexpr std::pair<std::string_view, std::string_view> kSuffixes[] = {
      {"_deg_s", "deg/s"}, {"_kgm2", "kg·m²"}, {"_years", "years"}, {"_deg", "deg"},
      {"_kg", "kg"},       {"_cm", "cm"},      {"_ma", "mA"},       {"_hz", "Hz"},
      {"_nm", "N·m"},      {"_ms", "ms"},      {"_s", "s"},         {"_m", "m"},
  };
  for (const auto& [suffix, unit] : kSuffixes) {
    if (key.ends_with(suffix)) return std::string(unit);
  }
  return "";
}

std::string Shortest(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.10g", value);
  return buffer;
}

// "weight_kg must be 1–400 kg, got -5": the field, its allowed range with
// the unit its name carries, and the value sent.
template <typename T>
std::string RangeMessage(std::string_view key, T min, T max, const std::string& got) {
  const std::string unit = UnitOf(key);
  const std::string with_unit = unit.empty() ? "" : " " + unit;
  const bool has_min = min > std::numeric_limits<T>::lowest();
  const bool has_max = max < std::numeric_limits<T>::max();
  std::string range;
  if (has_min && has_max) {
    range = Shortest(static_cast<double>(min)) + "–" + Shortest(static_cast<double>(max));
  } else if (has_min) {
    range = "≥ " + Shortest(static_cast<double>(min));
  } else if (has_max) {
    range = "≤ " + Shortest(static_cast<double>(max));
  } else {
    range = "finite";
  }
  return std::string(key) + " must be " + range + with_unit + ", got " + got;
}

}  // namespace

Result<nlohmann::json> ParseJsonObject(std::string_view body, const JsonLimits& limits) {
  if (body.empty()) return Status::InvalidArgument("request body is empty; expected a JSON object");
  if (NestingDepth(body, kMaxJsonDepth) > kMaxJsonDepth) {
    return Status::InvalidArgument("JSON nested deeper than " +
                                        std::to_string(kMaxJsonDepth) + " levels");
  }
  nlohmann::json json;
  PathTracker tracker(limits.max_values);
  try {
    json = nlohmann::json::parse(body, std::ref(tracker));
  } catch (const ParseRefusal& refusal) {
    return Status::InvalidArgument(refusal.message, refusal.path);
  } catch (const nlohmann::json::parse_error& e) {
    return Status::InvalidArgument("malformed JSON at byte " + std::to_string(e.byte) +
                                        ": " + e.what());
  } catch (const nlohmann::json::exception&) {
    // out_of_range.406: a number beyond the range of a double (1e400).
    return Status::InvalidArgument("number out of range (beyond ±1.8e308)", tracker.Path());
  }
  if (!json.is_object()) {
    return Status::InvalidArgument("expected a JSON object, got " + TypeName(json));
  }
  return json;
}

JsonFields::JsonFields(const nlohmann::json& object, std::string path)
    : object_(object), path_(std::move(path)) {
  if (!object_.is_object()) {
    status_ = Status::InvalidArgument("must be an object, got " + TypeName(object_), path_);
  }
}

std::string JsonFields::PathOf(std::string_view key) const {
  return path_.empty() ? std::string(key) : path_ + "." + std::string(key);
}

void JsonFields::Fail(std::string_view key, std::string message) {
  if (status_.ok()) status_ = Status::InvalidArgument(std::move(message), PathOf(key));
}

const nlohmann::json* JsonFields::Find(std::string_view key, bool required) {
  if (!status_.ok()) return nullptr;
  seen_.emplace(key);
  auto it = object_.find(key);
  if (it == object_.end() || it->is_null()) {
    if (required) Fail(key, "is required");
    return nullptr;
  }
  return &*it;
}

std::optional<std::string> JsonFields::String(std::string_view key, bool required,
                                              std::size_t max_length) {
  const auto* j = Find(key, required);
  if (!j) return std::nullopt;
  if (!j->is_string()) {
    Fail(key, "must be a string, got " + TypeName(*j));
    return std::nullopt;
  }
  const auto& s = j->get_ref<const std::string&>();
  if (s.size() > max_length) {
    Fail(key, "must be at most " + std::to_string(max_length) + " characters");
    return std::nullopt;
  }
  return s;
}

Status CheckPrintableText(std::string_view text, std::string_view field) {
  bool written = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    // C1 controls are U+0080–U+009F: 0xC2 0x80–0x9F in UTF-8.
    const bool c1 = c == 0xC2 && i + 1 < text.size() &&
                    static_cast<unsigned char>(text[i + 1]) >= 0x80 &&
                    static_cast<unsigned char>(text[i + 1]) <= 0x9F;
    if (c < 0x20 || c == 0x7F || c1) {
      return Status::InvalidArgument(
          "must be printable text: a control character at byte " + std::to_string(i),
          std::string(field));
    }
    written = written || c != ' ';
  }
  if (!written) {
    return Status::InvalidArgument("must be printable text, not empty or only spaces",
                                   std::string(field));
  }
  return Status::Ok();
}

std::optional<double> JsonFields::Number(std::string_view key, bool required, double min,
                                         double max) {
  const auto* j = Find(key, required);
  if (!j) return std::nullopt;
  if (!j->is_number()) {
    Fail(key, "must be a number, got " + TypeName(*j));
    return std::nullopt;
  }
  const double value = j->get<double>();
  if (!std::isfinite(value) || value < min || value > max) {
    Fail(key, RangeMessage(key, min, max, std::isfinite(value) ? Shortest(value) : j->dump()));
    return std::nullopt;
  }
  return value;
}

std::optional<std::int64_t> JsonFields::Integer(std::string_view key, bool required,
                                                std::int64_t min, std::int64_t max) {
  const auto* j = Find(key, required);
  if (!j) return std::nullopt;
  if (!j->is_number_integer()) {
    Fail(key, "must be an integer, got " + (j->is_number() ? j->dump() : TypeName(*j)));
    return std::nullopt;
  }
  if (j->is_number_unsigned() &&
      j->get<std::uint64_t>() > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) {
    Fail(key, "is out of range");
    return std::nullopt;
  }
  const auto value = j->get<std::int64_t>();
  if (value < min || value > max) {
    Fail(key, RangeMessage(key, min, max, std::to_string(value)));
    return std::nullopt;
  }
  return value;
}

std::optional<bool> JsonFields::Bool(std::string_view key, bool required) {
  const auto* j = Find(key, required);
  if (!j) return std::nullopt;
  if (!j->is_boolean()) {
    Fail(key, "must be true or false, got " + TypeName(*j));
    return std::nullopt;
  }
  return j->get<bool>();
}

std::optional<std::vector<std::int64_t>> JsonFields::IdList(std::string_view key, bool required,
                                                            std::size_t max_items) {
  const auto* j = Find(key, required);
  if (!j) return std::nullopt;
  if (!j->is_array()) {
    Fail(key, "must be an array of ids, got " + TypeName(*j));
    return std::nullopt;
  }
  if (j->size() > max_items) {
    Fail(key, "must hold at most " + std::to_string(max_items) + " ids");
    return std::nullopt;
  }
  std::vector<std::int64_t> ids;
  for (std::size_t i = 0; i < j->size(); ++i) {
    const auto& item = (*j)[i];
    const std::string item_key = std::string(key) + "[" + std::to_string(i) + "]";
    if (!item.is_number_integer() || (item.is_number_unsigned() && item.get<std::uint64_t>() >
                                          static_cast<std::uint64_t>(
                                              std::numeric_limits<std::int64_t>::max())) ||
        item.get<std::int64_t>() < 1) {
      Fail(item_key, "must be a positive integer id, got " + item.dump());
      return std::nullopt;
    }
    ids.push_back(item.get<std::int64_t>());
  }
  return ids;
}

const nlohmann::json* JsonFields::Object(std::string_view key, bool required) {
  const auto* j = Find(key, required);
  if (!j) return nullptr;
  if (!j->is_object()) {
    Fail(key, "must be an object, got " + TypeName(*j));
    return nullptr;
  }
  return j;
}

const nlohmann::json* JsonFields::Any(std::string_view key, bool required) {
  return Find(key, required);
}

Status JsonFields::Finish() {
  if (!status_.ok()) return status_;
  for (const auto& [key, value] : object_.items()) {
    if (!seen_.contains(key)) {
      Fail(key, "unknown field");
      break;
    }
  }
  return status_;
}

namespace {

// Long enough for any text a server sends back (descriptions, reasons).
constexpr std::size_t kAnyLength = std::size_t{1} << 20;

template <typename T>
void ReadArray(JsonFields& in, std::string_view key, std::vector<T>& out, const char* what) {
  const nlohmann::json* v = in.Any(key, false);
  if (v == nullptr) return;
  try {
    out = v->get<std::vector<T>>();
  } catch (const nlohmann::json::exception&) {
    in.Fail(key, std::string("must be an array of ") + what + ", got " + TypeName(*v));
  }
}

}  // namespace

void ReadInto(JsonFields& in, std::string_view key, double& out) {
  if (const auto v = in.Number(key, false)) out = *v;
}
void ReadInto(JsonFields& in, std::string_view key, bool& out) {
  if (const auto v = in.Bool(key, false)) out = *v;
}
void ReadInto(JsonFields& in, std::string_view key, std::string& out) {
  if (auto v = in.String(key, false, kAnyLength)) out = std::move(*v);
}
void ReadInto(JsonFields& in, std::string_view key, std::optional<double>& out) {
  if (const auto v = in.Number(key, false)) out = *v;
}
void ReadInto(JsonFields& in, std::string_view key, std::optional<std::string>& out) {
  if (auto v = in.String(key, false, kAnyLength)) out = std::move(*v);
}
void ReadInto(JsonFields& in, std::string_view key, std::vector<double>& out) {
  ReadArray(in, key, out, "numbers");
}
void ReadInto(JsonFields& in, std::string_view key, std::vector<std::string>& out) {
  ReadArray(in, key, out, "strings");
}
void ReadInto(JsonFields& in, std::string_view key, std::vector<std::int64_t>& out) {
  ReadArray(in, key, out, "integers");
}

}  // namespace fesbench::api
