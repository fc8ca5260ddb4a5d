#include "api/trial_import.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <numbers>
#include <set>
#include <tuple>

#include "api/trial_kind.h"

namespace fesbench::api {
namespace {

using nlohmann::json;

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
    s.remove_suffix(1);
  return s;
}

// Fields of one line: split at `sep`, or at runs of blanks when sep is ' '.
std::vector<std::string_view> Fields(std::string_view line, char sep) {
  std::vector<std::string_view> out;
  line = Trim(line);
  if (sep == ' ') {
    std::size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
      const std::size_t start = i;
      while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
      if (i > start) out.push_back(line.substr(start, i - start));
    }
    return out;
  }
  std::size_t start = 0;
  while (true) {
    const std::size_t end = line.find(sep, start);
    out.push_back(Trim(line.substr(start, end == std::string_view::npos ? end : end - start)));
    if (end == std::string_view::npos) return out;
    start = end + 1;
  }
}

std::optional<double> ParseNumber(std::string_view field) {
  if (field.empty()) return std::nullopt;
  if (field.front() == '+') field.remove_prefix(1);
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
  if (ec != std::errc() || ptr != field.data() + field.size()) return std::nullopt;
  return value;
}

std::string Num(double v) {
  char buffer[32];
  const auto [ptr, ec] = std::to_chars(buffer, buffer + sizeof buffer, v);
  return std::string(buffer, ec == std::errc() ? ptr : buffer);
}

std::string Quoted(std::string_view s) {
  constexpr std::size_t kMax = 40;
  return "'" + (s.size() > kMax ? std::string(s.substr(0, kMax)) + "..." : std::string(s)) + "'";
}

std::string At(std::size_t line, std::size_t column, std::string_view label) {
  return "line " + std::to_string(line) + ", column " + std::to_string(column) + " (" +
         std::string(label) + ")";
}

std::vector<std::string_view> Lines(std::string_view text) {
  if (text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);
  std::vector<std::string_view> lines;
  for (std::size_t start = 0; start <= text.size();) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    lines.push_back(text.substr(start, end - start));
    start = end + 1;
  }
  while (!lines.empty() && Trim(lines.back()).empty()) lines.pop_back();
  return lines;
}

// A unit and its factor to a base unit, per dimension.
struct UnitEntry {
  std::string_view unit;
  std::string_view dimension;
  double factor;  // value in this unit × factor = value in the dimension's base unit.
};

constexpr double kDeg = 180.0 / std::numbers::pi;

const UnitEntry kUnits[] = {
    {"s", "time", 1.0},          {"ms", "time", 1e-3},         {"us", "time", 1e-6},
    {"µs", "time", 1e-6},        {"deg", "angle", 1.0},        {"°", "angle", 1.0},
    {"rad", "angle", kDeg},      {"deg/s", "ang_vel", 1.0},    {"rad/s", "ang_vel", kDeg},
    {"deg/s^2", "ang_acc", 1.0}, {"rad/s^2", "ang_acc", kDeg}, {"N.m", "torque", 1.0},
    {"N·m", "torque", 1.0},      {"Nm", "torque", 1.0},        {"N.cm", "torque", 1e-2},
    {"N.mm", "torque", 1e-3},    {"Nmm", "torque", 1e-3},      {"mA", "current", 1.0},
    {"A", "current", 1e3},       {"uA", "current", 1e-3},      {"µA", "current", 1e-3},
    {"mV", "voltage", 1.0},      {"V", "voltage", 1e3},        {"uV", "voltage", 1e-3},
    {"µV", "voltage", 1e-3},     {"m/s^2", "accel", 1.0},      {"g", "accel", 9.80665},
    {"m", "length", 1.0},        {"cm", "length", 1e-2},       {"mm", "length", 1e-3},
    {"Hz", "frequency", 1.0},    {"1", "ratio", 1.0},          {"%", "ratio", 1e-2},
};

const UnitEntry* FindUnit(std::string_view unit) {
  for (const UnitEntry& e : kUnits) {
    if (e.unit == unit) return &e;
  }
  return nullptr;
}

std::string UnitsOf(std::string_view dimension) {
  std::string out;
  for (const UnitEntry& e : kUnits) {
    if (e.dimension != dimension) continue;
    if (!out.empty()) out += ", ";
    out += e.unit;
  }
  return out;
}

// --- JSON helpers -------------------------------------------------------------

Status Fail(const std::string& field, const std::string& message) {
  return Status::InvalidArgument(message, field);
}

Status GetString(const json& j, const char* key, std::string& out, const std::string& field) {
  if (!j.contains(key)) return Status::Ok();
  if (!j.at(key).is_string()) return Fail(field, "must be a string");
  out = j.at(key).get<std::string>();
  return Status::Ok();
}

Status GetStrings(const json& j, const char* key, std::vector<std::string>& out) {
  if (!j.contains(key)) return Status::Ok();
  const json& a = j.at(key);
  if (!a.is_array()) return Fail(key, "must be an array of strings");
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!a[i].is_string()) {
      return Fail(std::string(key) + "[" + std::to_string(i) + "]", "must be a string");
    }
    out.push_back(a[i].get<std::string>());
  }
  return Status::Ok();
}

}  // namespace

std::optional<double> UnitFactor(std::string_view from, std::string_view to) {
  const UnitEntry* f = FindUnit(from);
  const UnitEntry* t = FindUnit(to);
  if (f == nullptr || t == nullptr || f->dimension != t->dimension) return std::nullopt;
  if (f == t || f->factor == t->factor) return 1.0;
  return f->factor / t->factor;
}

std::optional<std::pair<double, double>> ChannelRange(std::string_view channel) {
  static const std::pair<std::string_view, std::pair<double, double>> kRanges[] = {
      {"angle_deg", {-90.0, 270.0}},         {"setpoint_deg", {-90.0, 270.0}},
      {"velocity_deg_s", {-5000.0, 5000.0}}, {"accel_deg_s2", {-2e5, 2e5}},
      {"torque_nm", {-1000.0, 1000.0}},      {"stim_ma", {0.0, 200.0}},
      {"stim_delivered_ma", {0.0, 200.0}},   {"activation", {-0.5, 1.5}},
      {"emg_mv", {-100.0, 100.0}},           {"accel_m_s2", {-2000.0, 2000.0}},
  };
  for (const auto& [name, range] : kRanges) {
    if (name == channel) return range;
  }
  return std::nullopt;
}

const std::vector<KnownColumn>& KnownColumns() {
  // OpenSim's gait models (gait2392, Rajagopal): knee flexion is negative.
  static const std::vector<KnownColumn> kKnown = {
      {"knee_angle_r", "angle_deg", -1, "OpenSim right knee angle (flexion negative)"},
      {"knee_angle_l", "angle_deg", -1, "OpenSim left knee angle (flexion negative)"},
      {"knee_angle_r_speed", "velocity_deg_s", -1, "OpenSim right knee angular speed"},
      {"knee_angle_l_speed", "velocity_deg_s", -1, "OpenSim left knee angular speed"},
  };
  return kKnown;
}

Result<ImportSpec> ImportSpecFromJson(const json& j) {
  if (!j.is_object()) return Fail("", "the import spec must be a JSON object");
  static const std::set<std::string> kKnown = {
      "kind",    "format", "time_column",        "time_unit", "sample_rate_hz",
      "columns", "ignore", "start_time_unix_ms", "source",    "unmapped", "stops_deg"};
  for (const auto& [key, value] : j.items()) {
    if (!kKnown.contains(key)) return Fail(key, "unknown field");
  }
  ImportSpec spec;
  if (!j.contains("kind")) return Fail("kind", "required (a trial kind, e.g. free_swing_passive)");
  if (Status s = GetString(j, "kind", spec.kind, "kind"); !s.ok()) return s;
  if (Status s = ValidateTrialKindName(spec.kind, "kind"); !s.ok()) return s;
  if (Status s = GetString(j, "format", spec.format, "format"); !s.ok()) return s;
  if (spec.format != "csv" && spec.format != "tsv" && spec.format != "sto") {
    return Fail("format", "must be csv, tsv or sto");
  }
  if (Status s = GetString(j, "time_column", spec.time_column, "time_column"); !s.ok()) return s;
  if (Status s = GetString(j, "time_unit", spec.time_unit, "time_unit"); !s.ok()) return s;
  if (!UnitFactor(spec.time_unit, "s")) return Fail("time_unit", "must be s, ms or us");
  if (j.contains("sample_rate_hz")) {
    const json& r = j.at("sample_rate_hz");
    if (!r.is_number() || !std::isfinite(r.get<double>()) || r.get<double>() <= 0.0 ||
        r.get<double>() > 100000.0) {
      return Fail("sample_rate_hz", "must be a number of Hz in (0, 100000]");
    }
    spec.sample_rate_hz = r.get<double>();
  }
  if (j.contains("columns")) {
    const json& cols = j.at("columns");
    if (!cols.is_array()) return Fail("columns", "must be an array of {column, channel, unit}");
    for (std::size_t i = 0; i < cols.size(); ++i) {
      const std::string f = "columns[" + std::to_string(i) + "]";
      if (!cols[i].is_object()) return Fail(f, "must be an object {column, channel, unit}");
      static const std::set<std::string> kColumnKeys = {"column", "channel", "unit",
                                                         "sign",   "scale",   "offset"};
      for (const auto& [key, value] : cols[i].items()) {
        if (!kColumnKeys.contains(key)) return Fail(f + "." + key, "unknown field");
      }
      ImportColumn c;
      if (Status s = GetString(cols[i], "column", c.column, f + ".column"); !s.ok()) return s;
      if (Status s = GetString(cols[i], "channel", c.channel, f + ".channel"); !s.ok()) return s;
      if (Status s = GetString(cols[i], "unit", c.unit, f + ".unit"); !s.ok()) return s;
      if (c.column.empty()) return Fail(f + ".column", "required (the column's label in the file)");
      const auto known = std::find_if(KnownColumns().begin(), KnownColumns().end(),
                                      [&](const KnownColumn& k) { return k.column == c.column; });
      if (known != KnownColumns().end() && !cols[i].contains("channel")) {
        // A known label alone: its channel and its sign (an explicit sign wins).
        c.channel = std::string(known->channel);
        c.sign = known->sign;
      }
      if (cols[i].contains("sign")) {
        const json& v = cols[i].at("sign");
        if (!v.is_number_integer() || (v.get<int>() != 1 && v.get<int>() != -1)) {
          return Fail(f + ".sign", "must be 1 or -1");
        }
        c.sign = v.get<int>();
      }
      for (const auto& [key, target, nonzero] :
           {std::tuple<const char*, double*, bool>{"scale", &c.scale, true},
            std::tuple<const char*, double*, bool>{"offset", &c.offset, false}}) {
        if (!cols[i].contains(key)) continue;
        const json& v = cols[i].at(key);
        if (!v.is_number() || !std::isfinite(v.get<double>()) ||
            (nonzero && !(v.get<double>() > 0.0)) || std::abs(v.get<double>()) > 1e6) {
          return Fail(f + "." + key, nonzero ? "must be a finite number > 0 (use sign for −1)"
                                             : "must be a finite number (in the channel's unit)");
        }
        *target = v.get<double>();
      }
      if (!IsValidChannelName(c.channel) || c.channel == kTimeChannel) {
        return Fail(f + ".channel",
                    "must be a channel name such as angle_deg, torque_nm or stim_ma (not t_s)");
      }
      spec.columns.push_back(std::move(c));
    }
  }
  if (Status s = GetStrings(j, "ignore", spec.ignore); !s.ok()) return s;
  if (j.contains("unmapped")) {
    const json& u = j.at("unmapped");
    if (!u.is_string() || (u.get<std::string>() != "refuse" && u.get<std::string>() != "ignore")) {
      return Fail("unmapped", "must be \"refuse\" (the default) or \"ignore\"");
    }
    spec.ignore_unmapped = u.get<std::string>() == "ignore";
  }
  if (j.contains("start_time_unix_ms")) {
    if (!j.at("start_time_unix_ms").is_number_integer()) {
      return Fail("start_time_unix_ms", "must be an integer (ms since 1970 UTC)");
    }
    spec.start_time_unix_ms = j.at("start_time_unix_ms").get<std::int64_t>();
  }
  if (Status s = GetString(j, "source", spec.source, "source"); !s.ok()) return s;
  if (spec.source.size() > 500) return Fail("source", "must be at most 500 characters");
  if (j.contains("stops_deg")) {
    const json& st = j.at("stops_deg");
    const auto angle = [](const json& v) {
      return v.is_number() && std::isfinite(v.get<double>()) && v.get<double>() >= -30.0 &&
             v.get<double>() <= 180.0;
    };
    if (!st.is_array() || st.size() != 2 || !angle(st[0]) || !angle(st[1]) ||
        !(st[0].get<double>() < st[1].get<double>())) {
      return Fail("stops_deg", "must be [min, max] in deg, −30 ≤ min < max ≤ 180 (the rig's stops)");
    }
    spec.stops_deg = {st[0].get<double>(), st[1].get<double>()};
  }
  return spec;
}

json ImportSpecToJson(const ImportSpec& spec) {
  json j = {{"kind", spec.kind}, {"format", spec.format}, {"time_unit", spec.time_unit}};
  if (!spec.time_column.empty()) j["time_column"] = spec.time_column;
  if (spec.sample_rate_hz) j["sample_rate_hz"] = *spec.sample_rate_hz;
  json cols = json::array();
  for (const ImportColumn& c : spec.columns) {
    json col = {{"column", c.column}, {"channel", c.channel}, {"unit", c.unit}};
    if (c.sign != 1) col["sign"] = c.sign;
    if (c.scale != 1.0) col["scale"] = c.scale;
    if (c.offset != 0.0) col["offset"] = c.offset;
    cols.push_back(std::move(col));
  }
  j["columns"] = std::move(cols);
  j["ignore"] = spec.ignore;
  if (spec.ignore_unmapped) j["unmapped"] = "ignore";
  if (spec.stops_deg) j["stops_deg"] = {spec.stops_deg->first, spec.stops_deg->second};
  if (spec.start_time_unix_ms) j["start_time_unix_ms"] = *spec.start_time_unix_ms;
  if (!spec.source.empty()) j["source"] = spec.source;
  return j;
}

Result<TextTable> ReadTextTable(std::string_view text, std::string_view format,
                                const std::vector<std::string>* labels) {
  const std::vector<std::string_view> lines = Lines(text);
  if (lines.empty()) return Status::InvalidArgument("empty file");
  TextTable table;
  std::size_t header = 0;  // index of the label row (or of the first data row).
  char sep = format == "csv" ? ',' : '\t';
  if (format == "sto") {
    while (header < lines.size() && Trim(lines[header]) != "endheader") {
      const std::string_view l = Trim(lines[header]);
      if (l == "inDegrees=no") table.in_degrees = false;
      ++header;
    }
    if (header == lines.size()) {
      return Status::InvalidArgument("no 'endheader' line: not an OpenSim Storage (.sto) file");
    }
    ++header;
    if (header == lines.size()) {
      return Status::InvalidArgument("line " + std::to_string(header + 1) +
                                     ": missing the column labels after 'endheader'");
    }
    if (lines[header].find('\t') == std::string_view::npos) sep = ' ';
  }
  if (labels != nullptr) {
    table.labels = *labels;
  } else {
    const std::vector<std::string_view> names = Fields(lines[header], sep);
    for (std::size_t j = 0; j < names.size(); ++j) {
      const std::size_t line_no = header + 1;
      if (names[j].empty()) {
        return Status::InvalidArgument("line " + std::to_string(line_no) + ", column " +
                                       std::to_string(j + 1) + ": empty column label");
      }
      if (ParseNumber(names[j])) {
        return Status::InvalidArgument("line " + std::to_string(line_no) +
                                       ": missing header row (found the number " +
                                       Quoted(names[j]) + " where column labels belong)");
      }
      if (std::find(table.labels.begin(), table.labels.end(), names[j]) != table.labels.end()) {
        return Status::InvalidArgument("line " + std::to_string(line_no) + ", column " +
                                       std::to_string(j + 1) + ": duplicate column label " +
                                       Quoted(names[j]));
      }
      table.labels.emplace_back(names[j]);
    }
    ++header;
  }
  table.first_data_line = header + 1;
  if (header >= lines.size()) return Status::InvalidArgument("no data rows");
  table.columns.assign(table.labels.size(), {});
  for (auto& c : table.columns) c.reserve(lines.size() - header);
  for (std::size_t i = header; i < lines.size(); ++i) {
    const std::size_t line_no = i + 1;
    if (Trim(lines[i]).empty()) {
      return Status::InvalidArgument("line " + std::to_string(line_no) + ": blank line");
    }
    const std::vector<std::string_view> fields = Fields(lines[i], sep);
    if (fields.size() != table.labels.size()) {
      return Status::InvalidArgument("line " + std::to_string(line_no) + ": expected " +
                                     std::to_string(table.labels.size()) + " columns, found " +
                                     std::to_string(fields.size()));
    }
    for (std::size_t j = 0; j < fields.size(); ++j) {
      const std::optional<double> v = ParseNumber(fields[j]);
      if (!v) {
        return Status::InvalidArgument(At(line_no, j + 1, table.labels[j]) + ": " +
                                       Quoted(fields[j]) + " is not a number");
      }
      if (!std::isfinite(*v)) {
        return Status::InvalidArgument(At(line_no, j + 1, table.labels[j]) + ": " +
                                       Quoted(fields[j]) + " is not a finite number");
      }
      table.columns[j].push_back(*v);
    }
  }
  return table;
}

Result<Trial> TrialFromTable(const TextTable& table, const ImportSpec& spec) {
  const TrialKindInfo* kind = FindTrialKind(spec.kind);
  if (kind == nullptr) return ValidateTrialKindName(spec.kind, "kind");
  auto column_of = [&](std::string_view label) -> std::optional<std::size_t> {
    const auto it = std::find(table.labels.begin(), table.labels.end(), label);
    if (it == table.labels.end()) return std::nullopt;
    return static_cast<std::size_t>(it - table.labels.begin());
  };
  auto labels_list = [&] {
    std::string out;
    for (const std::string& l : table.labels) out += (out.empty() ? "" : ", ") + Quoted(l);
    return out;
  };

  // Time.
  const std::string time_label = !spec.time_column.empty()
                                     ? spec.time_column
                                     : std::string(spec.format == "sto" ? "time" : kTimeChannel);
  const std::optional<std::size_t> time_col = column_of(time_label);
  if (!time_col) {
    return Fail("time_column", "the file has no time column " + Quoted(time_label) +
                                   " (its columns: " + labels_list() + ")");
  }
  const std::optional<double> time_factor = UnitFactor(spec.time_unit, "s");
  if (!time_factor) return Fail("time_unit", "must be s, ms or us");
  const std::size_t n = table.num_rows();
  if (n < 2) return Status::InvalidArgument("at least two rows of samples are needed");
  std::vector<double> t(n);
  for (std::size_t i = 0; i < n; ++i) t[i] = table.columns[*time_col][i] * *time_factor;
  const std::string time_at_col =
      ", column " + std::to_string(*time_col + 1) + " (" + time_label + ")";
  for (std::size_t i = 1; i < n; ++i) {
    if (!(t[i] > t[i - 1])) {
      return Status::InvalidArgument("line " + std::to_string(table.first_data_line + i) +
                                     time_at_col + ": time " + Num(t[i]) +
                                     " s is not after the previous " + Num(t[i - 1]) + " s");
    }
  }
  // Uniform sampling: every interval within 10 % of the median one.
  std::vector<double> dts(n - 1);
  for (std::size_t i = 1; i < n; ++i) dts[i - 1] = t[i] - t[i - 1];
  std::nth_element(dts.begin(), dts.begin() + static_cast<std::ptrdiff_t>(dts.size() / 2),
                   dts.end());
  const double median_dt = dts[dts.size() / 2];
  for (std::size_t i = 1; i < n; ++i) {
    const double dt = t[i] - t[i - 1];
    if (std::abs(dt - median_dt) > 0.1 * median_dt) {
      return Status::InvalidArgument(
          "line " + std::to_string(table.first_data_line + i) + time_at_col + ": interval " +
          Num(dt) + " s after the previous sample, the recording's is " + Num(median_dt) + " s (" +
          Num(1.0 / median_dt) +
          " Hz): sampling must be uniform within 10 % (resample, or split the recording)");
    }
  }
  const double mean_dt = (t.back() - t.front()) / static_cast<double>(n - 1);
  double rate = 1.0 / mean_dt;
  // Identification needs the bench's kind of rate (200 Hz); far outside it
  // the time unit is usually wrong (ms read as s).
  constexpr double kMinRateHz = 20.0;
  constexpr double kMaxRateHz = 20000.0;
  if (rate < kMinRateHz || rate > kMaxRateHz) {
    return Fail("time_unit", "the time column " + Quoted(time_label) + " read in " +
                                 spec.time_unit + " gives " + Num(rate) +
                                 " Hz, outside 20–20000 Hz: is the time unit right (s, ms, us)?");
  }
  if (spec.sample_rate_hz) {
    if (std::abs(rate - *spec.sample_rate_hz) > 0.01 * *spec.sample_rate_hz) {
      return Fail("sample_rate_hz",
                  "the time column " + Quoted(time_label) + " gives " + Num(rate) + " Hz (lines " +
                      std::to_string(table.first_data_line) + "–" +
                      std::to_string(table.first_data_line + n - 1) + "), the declared rate is " +
                      Num(*spec.sample_rate_hz) + " Hz (check time_unit)");
    }
    rate = *spec.sample_rate_hz;
  }

  // Which columns become which channels, with what factor.
  struct Take {
    std::size_t column;
    std::string channel;
    double factor;        // unit conversion × sign × scale
    double offset = 0.0;  // in the channel's unit
  };
  std::vector<Take> takes;
  std::set<std::string> channels = {std::string(kTimeChannel)};
  std::set<std::size_t> used = {*time_col};
  for (std::size_t i = 0; i < spec.columns.size(); ++i) {
    const ImportColumn& m = spec.columns[i];
    const std::string f = "columns[" + std::to_string(i) + "]";
    const std::optional<std::size_t> col = column_of(m.column);
    if (!col) {
      return Fail(f + ".column", "the file has no column " + Quoted(m.column) +
                                     " (its columns: " + labels_list() + ")");
    }
    if (!used.insert(*col).second) {
      return Fail(f + ".column", "column " + Quoted(m.column) + " is mapped twice");
    }
    if (!channels.insert(m.channel).second) {
      return Fail(f + ".channel", "channel " + m.channel + " is mapped twice");
    }
    const std::string target = ChannelUnit(m.channel);
    std::string from = m.unit;
    if (from.empty()) {
      from = target;
      if (!table.in_degrees && (target == "deg" || target == "deg/s" || target == "deg/s^2")) {
        from = target == "deg" ? "rad" : target == "deg/s" ? "rad/s" : "rad/s^2";
      }
    }
    double factor = 1.0;
    if (from != target) {
      const std::optional<double> k = UnitFactor(from, target);
      if (!k) {
        const UnitEntry* t_entry = FindUnit(target);
        return Fail(f + ".unit",
                    target.empty()
                        ? "channel " + m.channel + " has no unit to convert " + Quoted(from) +
                              " into; name the channel by its unit (e.g. angle_deg, torque_nm)"
                        : "cannot convert " + Quoted(from) + " into " + target + " (accepted: " +
                              (t_entry ? UnitsOf(t_entry->dimension) : target) + ")");
      }
      factor = *k;
    }
    takes.push_back({*col, m.channel, factor * m.sign * m.scale, m.offset});
  }
  for (std::size_t i = 0; i < spec.ignore.size(); ++i) {
    const std::optional<std::size_t> col = column_of(spec.ignore[i]);
    if (!col) {
      return Fail("ignore[" + std::to_string(i) + "]",
                  "the file has no column " + Quoted(spec.ignore[i]));
    }
    used.insert(*col);
  }
  for (std::size_t j = 0; j < table.labels.size(); ++j) {
    if (used.contains(j)) continue;
    const std::string& label = table.labels[j];
    // Only a channel name with a unit is taken as it is; anything else is
    // refused or, with "unmapped": "ignore", left out (never stored unit-less).
    if (channels.contains(label)) {
      return Fail("columns", "column " + std::to_string(j + 1) + " " + Quoted(label) +
                                 " is channel " + label +
                                 ", which another column is mapped to: list one in ignore");
    }
    if (!IsValidChannelName(label) || ChannelUnit(label).empty()) {
      if (spec.ignore_unmapped) continue;
      return Fail("columns", "column " + std::to_string(j + 1) + " " + Quoted(label) +
                                 " is not a fesbench channel name with a unit: map it (columns: "
                                 "[{\"column\": ..., \"channel\": ..., \"unit\": ...}]), "
                                 "list it in ignore, or set \"unmapped\": \"ignore\"");
    }
    channels.insert(label);
    takes.push_back({j, label, 1.0, 0.0});
  }
  for (std::string_view need : kind->required_channels) {
    if (!channels.contains(std::string(need))) {
      return Fail("columns", "missing channel " + std::string(need) + ", which a " +
                                 std::string(kind->name) +
                                 " trial needs: map a column of the file to it");
    }
  }

  Trial trial;
  trial.name = spec.kind;
  trial.start_time_unix_ms = spec.start_time_unix_ms;
  trial.sample_rate_hz = rate;
  trial.SetChannel(std::string(kTimeChannel), std::move(t));
  for (const Take& take : takes) {
    std::vector<double> v = table.columns[take.column];
    if (take.factor != 1.0 || take.offset != 0.0) {
      for (double& x : v) x = x * take.factor + take.offset;
    }
    if (const auto range = ChannelRange(take.channel)) {
      for (std::size_t i = 0; i < v.size(); ++i) {
        if (v[i] < range->first || v[i] > range->second) {
          const std::string unit = ChannelUnit(take.channel);
          return Status::InvalidArgument(
              At(table.first_data_line + i, take.column + 1, table.labels[take.column]) + ": " +
              Num(v[i]) + " " + unit + " is outside the range of " + take.channel + " (" +
              Num(range->first) + " to " + Num(range->second) + " " + unit +
              "); check the column's unit");
        }
      }
    }
    trial.SetChannel(take.channel, std::move(v));
  }
  if (Status s = ValidateTrial(trial); !s.ok()) return s;
  return trial;
}

Result<Trial> ImportTrialText(std::string_view text, const ImportSpec& spec) {
  Result<TextTable> table = ReadTextTable(text, spec.format);
  if (!table.ok()) return table.status();
  return TrialFromTable(*table, spec);
}

}  // namespace fesbench::api
