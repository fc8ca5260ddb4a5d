#include "api/trial.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <system_error>
#include <unordered_set>
#include <utility>

namespace fesbench::api {
namespace {

bool EndsWith(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
    s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> SplitFields(std::string_view line, char sep) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  while (true) {
    const std::size_t end = line.find(sep, start);
    if (end == std::string_view::npos) {
      fields.push_back(Trim(line.substr(start)));
      return fields;
    }
    fields.push_back(Trim(line.substr(start, end - start)));
    start = end + 1;
  }
}

// Parses the whole field as a double; nullopt if it is not exactly a number.
std::optional<double> ParseDouble(std::string_view field) {
  if (field.empty()) return std::nullopt;
  if (field.front() == '+') field.remove_prefix(1);
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
  if (ec != std::errc() || ptr != field.data() + field.size()) return std::nullopt;
  return value;
}

void AppendNumber(std::string& out, double value) {
  char buffer[32];
  const auto [ptr, ec] = std::to_chars(buffer, buffer + sizeof buffer, value);
  out.append(buffer, ec == std::errc() ? ptr : buffer);
}

std::string Quoted(std::string_view s) {
  constexpr std::size_t kMax = 40;
  std::string q = "'";
  q += s.size() > kMax ? std::string(s.substr(0, kMax)) + "..." : std::string(s);
  q += "'";
  return q;
}

std::string Where(std::size_t line, std::size_t column, std::string_view name) {
  std::string s = "line " + std::to_string(line) + ", column " + std::to_string(column);
  if (!name.empty()) s += " (" + std::string(name) + ")";
  return s;
}

template <typename Group>
auto* FindIn(Group& channels, std::string_view name) {
  auto it = std::find_if(channels.begin(), channels.end(),
                         [&](const Channel& c) { return c.name == name; });
  return it == channels.end() ? nullptr : &*it;
}

Channel& SetIn(std::vector<Channel>& channels, std::string name, std::vector<double> values) {
  if (Channel* c = FindIn(channels, name)) {
    c->values = std::move(values);
    return *c;
  }
  std::string unit = ChannelUnit(name);
  channels.push_back({std::move(name), std::move(unit), std::move(values)});
  return channels.back();
}

std::size_t NumSamples(const std::vector<Channel>& channels) {
  return channels.empty() ? 0 : channels.front().values.size();
}

}  // namespace

// --- ChannelGroup, Trial ------------------------------------------------------

const Channel* ChannelGroup::Find(std::string_view name) const { return FindIn(channels, name); }
Channel* ChannelGroup::Find(std::string_view name) { return FindIn(channels, name); }
const std::vector<double>* ChannelGroup::Values(std::string_view name) const {
  const Channel* c = Find(name);
  return c ? &c->values : nullptr;
}
Channel& ChannelGroup::Set(std::string name, std::vector<double> values) {
  return SetIn(channels, std::move(name), std::move(values));
}
std::size_t ChannelGroup::num_samples() const { return NumSamples(channels); }

const Channel* Trial::FindChannel(std::string_view name) const { return FindIn(channels, name); }
Channel* Trial::FindChannel(std::string_view name) { return FindIn(channels, name); }
const std::vector<double>* Trial::Values(std::string_view name) const {
  const Channel* c = FindChannel(name);
  return c ? &c->values : nullptr;
}
Channel& Trial::SetChannel(std::string name, std::vector<double> values) {
  return SetIn(channels, std::move(name), std::move(values));
}
std::size_t Trial::num_samples() const { return NumSamples(channels); }

std::string ChannelUnit(std::string_view name) {
  // Longest suffixes first: "_deg_s2" before "_deg_s" before "_s".
  static constexpr std::pair<std::string_view, std::string_view> kSuffixes[] = {
      {"_deg_s2", "deg/s^2"}, {"_deg_s", "deg/s"}, {"_m_s2", "m/s^2"}, {"_deg", "deg"},
      {"_ms", "ms"},          {"_ma", "mA"},       {"_nm", "N.m"},     {"_mv", "mV"},
      {"_hz", "Hz"},          {"_gain", "1"},      {"_s", "s"},        {"_m", "m"},
  };
  if (name == "activation") return "1";
  for (const auto& [suffix, unit] : kSuffixes) {
    if (EndsWith(name, suffix) && name.size() > suffix.size()) return std::string(unit);
  }
  return "";
}

bool IsValidChannelName(std::string_view name) {
  if (name.empty() || name.size() > 64) return false;
  if (name.front() < 'a' || name.front() > 'z') return false;
  return std::all_of(name.begin(), name.end(), [](char ch) {
    return (ch >= 'a' && ch <= 'z') || (ch >= '0' && ch <= '9') || ch == '_';
  });
}

Status ValidateChannelGroup(const ChannelGroup& group, std::string_view field_prefix) {
  const std::string prefix(field_prefix);
  if (!std::isfinite(group.sample_rate_hz) || group.sample_rate_hz <= 0.0) {
    return Status::InvalidArgument("must be a finite number > 0", prefix + "sample_rate_hz");
  }
  std::unordered_set<std::string_view> seen;
  const std::size_t n = group.num_samples();
  for (std::size_t i = 0; i < group.channels.size(); ++i) {
    const Channel& c = group.channels[i];
    const std::string field = prefix + "channels[" + std::to_string(i) + "]";
    if (!IsValidChannelName(c.name)) {
      return Status::InvalidArgument(
          "invalid channel name " + Quoted(c.name) + " (want [a-z][a-z0-9_]*)", field + ".name");
    }
    if (!seen.insert(c.name).second) {
      return Status::InvalidArgument("duplicate channel name " + Quoted(c.name), field + ".name");
    }
    if (c.values.size() != n) {
      return Status::InvalidArgument("channel " + c.name + " has " +
                                         std::to_string(c.values.size()) + " samples, expected " +
                                         std::to_string(n),
                                     field + ".values");
    }
    for (std::size_t k = 0; k < n; ++k) {
      if (!std::isfinite(c.values[k])) {
        return Status::InvalidArgument("value is not finite",
                                       field + ".values[" + std::to_string(k) + "]");
      }
    }
  }
  const Channel* t = group.Find(kTimeChannel);
  if (t == nullptr) {
    return Status::InvalidArgument("no t_s (time) channel", prefix + "channels");
  }
  for (std::size_t k = 1; k < t->values.size(); ++k) {
    if (!(t->values[k] > t->values[k - 1])) {
      const auto index = static_cast<std::size_t>(t - group.channels.data());
      return Status::InvalidArgument(
          "t_s is not strictly increasing at sample " + std::to_string(k),
          prefix + "channels[" + std::to_string(index) + "].values[" + std::to_string(k) + "]");
    }
  }
  return Status::Ok();
}

model::PulseTrain PulseRecord::Train() const {
  model::PulseTrain out;
  out.reserve(t_s.size());
  for (std::size_t i = 0; i < t_s.size() && i < stim_ma.size(); ++i)
    out.push_back({t_s[i], stim_ma[i]});
  return out;
}

void PulseRecord::Append(double t_s_value, double stim_ma_value) {
  t_s.push_back(t_s_value);
  stim_ma.push_back(stim_ma_value);
}

Status ValidateDeviceCommandLog(const DeviceCommandLog& log) {
  const std::string f = "device_commands.";
  if (log.device.empty() || log.device.size() > 64) {
    return Status::InvalidArgument("must be 1–64 characters", f + "device");
  }
  if (!std::isfinite(log.pulse_rate_hz) || log.pulse_rate_hz <= 0.0) {
    return Status::InvalidArgument("must be a finite number > 0", f + "pulse_rate_hz");
  }
  if (!std::isfinite(log.current_step_ma) || log.current_step_ma <= 0.0) {
    return Status::InvalidArgument("must be a finite number > 0", f + "current_step_ma");
  }
  const std::size_t n = log.t_s.size();
  for (const auto& [name, size] : {std::pair{"requested_ma", log.requested_ma.size()},
                                   std::pair{"commanded_ma", log.commanded_ma.size()},
                                   std::pair{"single_pulse", log.single_pulse.size()}}) {
    if (size != n) {
      return Status::InvalidArgument(
          "has " + std::to_string(size) + " values, t_s has " + std::to_string(n), f + name);
    }
  }
  for (std::size_t k = 0; k < n; ++k) {
    const std::string at = "[" + std::to_string(k) + "]";
    if (!std::isfinite(log.t_s[k])) return Status::InvalidArgument("value is not finite", f + "t_s" + at);
    if (k > 0 && !(log.t_s[k] >= log.t_s[k - 1])) {
      return Status::InvalidArgument("command times decrease", f + "t_s" + at);
    }
    for (const auto& [name, v] : {std::pair{"requested_ma", log.requested_ma[k]},
                                  std::pair{"commanded_ma", log.commanded_ma[k]}}) {
      if (!std::isfinite(v) || v < 0.0) {
        return Status::InvalidArgument("must be a finite number >= 0", f + name + at);
      }
    }
    if (log.commanded_ma[k] > log.requested_ma[k] + 1e-9) {
      return Status::InvalidArgument("is above the requested amplitude", f + "commanded_ma" + at);
    }
  }
  return Status::Ok();
}

Status ValidatePulseRecord(const PulseRecord& pulses) {
  if (!std::isfinite(pulses.pulse_rate_hz) || pulses.pulse_rate_hz <= 0.0) {
    return Status::InvalidArgument("must be a finite number > 0", "pulses.pulse_rate_hz");
  }
  if (!std::isfinite(pulses.pulse_width_us) || pulses.pulse_width_us <= 0.0) {
    return Status::InvalidArgument("must be a finite number > 0", "pulses.pulse_width_us");
  }
  if (pulses.stim_ma.size() != pulses.t_s.size()) {
    return Status::InvalidArgument("has " + std::to_string(pulses.stim_ma.size()) +
                                       " values, t_s has " + std::to_string(pulses.t_s.size()),
                                   "pulses.stim_ma");
  }
  for (std::size_t k = 0; k < pulses.t_s.size(); ++k) {
    const std::string at = "[" + std::to_string(k) + "]";
    if (!std::isfinite(pulses.t_s[k])) {
      return Status::InvalidArgument("value is not finite", "pulses.t_s" + at);
    }
    if (k > 0 && !(pulses.t_s[k] >= pulses.t_s[k - 1])) {
      return Status::InvalidArgument("pulse times decrease", "pulses.t_s" + at);
    }
    if (!std::isfinite(pulses.stim_ma[k]) || pulses.stim_ma[k] < 0.0) {
      return Status::InvalidArgument("must be a finite number >= 0", "pulses.stim_ma" + at);
    }
  }
  return Status::Ok();
}

namespace {

// A set kind must be the kind of a set name.
Status ValidateKindOfName(const Trial& trial) {
  if (trial.kind && trial.name && TrialKindOf(*trial.name) != trial.kind) {
    return Status::InvalidArgument("a trial named '" + *trial.name + "' is not of kind '" +
                                       std::string(TrialKindName(*trial.kind)) + "'",
                                   "kind");
  }
  return Status::Ok();
}

}  // namespace

Status ValidateTrial(const Trial& trial) {
  if (Status s = ValidateChannelGroup(trial.MainGroup()); !s.ok()) return s;
  if (trial.emg) {
    if (Status s = ValidateChannelGroup(*trial.emg, "emg."); !s.ok()) return s;
  }
  if (trial.device_commands) {
    if (Status s = ValidateDeviceCommandLog(*trial.device_commands); !s.ok()) return s;
  }
  if (trial.pulses) {
    if (Status s = ValidatePulseRecord(*trial.pulses); !s.ok()) return s;
  }
  return ValidateKindOfName(trial);
}

// --- CSV ----------------------------------------------------------------------

std::string GroupToCsv(const ChannelGroup& group) {
  std::string out;
  const std::size_t n = group.num_samples();
  out.reserve((n + 1) * group.channels.size() * 12);
  for (std::size_t j = 0; j < group.channels.size(); ++j) {
    if (j) out += ',';
    out += group.channels[j].name;
  }
  out += '\n';
  for (std::size_t k = 0; k < n; ++k) {
    for (std::size_t j = 0; j < group.channels.size(); ++j) {
      if (j) out += ',';
      const auto& values = group.channels[j].values;
      if (k < values.size()) AppendNumber(out, values[k]);
    }
    out += '\n';
  }
  return out;
}

std::string TrialToCsv(const Trial& trial) { return GroupToCsv(trial.MainGroup()); }

Result<ChannelGroup> GroupFromCsv(std::string_view text, double default_rate_hz) {
  if (text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);
  if (text.find_first_not_of(" \t\r\n") == std::string_view::npos) {
    return Status::InvalidArgument("empty file: expected a header row of channel names");
  }
  // Split into lines, remembering 1-based line numbers.
  std::vector<std::string_view> lines;
  for (std::size_t start = 0; start <= text.size();) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    lines.push_back(text.substr(start, end - start));
    start = end + 1;
  }
  while (!lines.empty() && Trim(lines.back()).empty()) lines.pop_back();

  // Header.
  const std::vector<std::string_view> names = SplitFields(lines.front(), ',');
  ChannelGroup group;
  bool numeric_header = true;
  for (std::string_view name : names) numeric_header = numeric_header && ParseDouble(name);
  if (numeric_header) {
    return Status::InvalidArgument(
        "line 1: missing header row (expected channel names such as t_s,stim_ma, found numbers)");
  }
  for (std::size_t j = 0; j < names.size(); ++j) {
    const std::string_view name = names[j];
    if (name.empty()) {
      return Status::InvalidArgument(Where(1, j + 1, {}) + ": empty channel name");
    }
    if (!IsValidChannelName(name)) {
      return Status::InvalidArgument(Where(1, j + 1, {}) + ": invalid channel name " +
                                     Quoted(name) + " (want [a-z][a-z0-9_]*, e.g. angle_deg)");
    }
    if (group.Find(name)) {
      return Status::InvalidArgument(Where(1, j + 1, {}) + ": duplicate channel name " +
                                     Quoted(name));
    }
    group.channels.push_back({std::string(name), ChannelUnit(name), {}});
  }
  const Channel* time_channel = group.Find(kTimeChannel);
  if (time_channel == nullptr) {
    return Status::InvalidArgument("line 1: no t_s column in the header");
  }
  const auto time_column = static_cast<std::size_t>(time_channel - group.channels.data());
  if (lines.size() < 2) {
    return Status::InvalidArgument("no data rows after the header");
  }

  for (Channel& c : group.channels) c.values.reserve(lines.size() - 1);
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const std::size_t line_no = i + 1;
    if (Trim(lines[i]).empty()) {
      return Status::InvalidArgument("line " + std::to_string(line_no) + ": blank line");
    }
    const std::vector<std::string_view> fields = SplitFields(lines[i], ',');
    if (fields.size() != names.size()) {
      return Status::InvalidArgument("line " + std::to_string(line_no) + ": expected " +
                                     std::to_string(names.size()) + " columns, found " +
                                     std::to_string(fields.size()));
    }
    for (std::size_t j = 0; j < fields.size(); ++j) {
      Channel& c = group.channels[j];
      const std::optional<double> value = ParseDouble(fields[j]);
      if (!value) {
        return Status::InvalidArgument(
            Where(line_no, j + 1, c.name) + ": " + Quoted(fields[j]) + " is not a number", c.name);
      }
      if (!std::isfinite(*value)) {
        return Status::InvalidArgument(
            Where(line_no, j + 1, c.name) + ": " + Quoted(fields[j]) + " is not finite", c.name);
      }
      if (j == time_column && !c.values.empty() && !(*value > c.values.back())) {
        std::string previous;
        AppendNumber(previous, c.values.back());
        return Status::InvalidArgument(Where(line_no, j + 1, c.name) + ": time " +
                                           std::string(fields[j]) +
                                           " is not greater than the previous " + previous,
                                       c.name);
      }
      c.values.push_back(*value);
    }
  }
  const std::vector<double>& t = *group.Values(kTimeChannel);
  group.sample_rate_hz =
      t.size() >= 2 ? static_cast<double>(t.size() - 1) / (t.back() - t.front()) : default_rate_hz;
  if (!std::isfinite(group.sample_rate_hz) || group.sample_rate_hz <= 0.0) {
    return Status::InvalidArgument("sample rate must be a finite number > 0", "sample_rate_hz");
  }
  return group;
}

Result<Trial> TrialFromCsv(std::string_view text, double default_rate_hz) {
  Result<ChannelGroup> group = GroupFromCsv(text, default_rate_hz);
  if (!group.ok()) return group.status();
  Trial trial;
  trial.sample_rate_hz = group->sample_rate_hz;
  trial.channels = std::move(group->channels);
  return trial;
}

// --- OpenSim Storage ------------------------------------------------------------

std::string GroupToSto(const ChannelGroup& group, std::string_view name,
                       const std::vector<std::pair<std::string, std::string>>& metadata) {
  const Channel* time_channel = group.Find(kTimeChannel);
  std::vector<const Channel*> columns;
  if (time_channel) columns.push_back(time_channel);
  for (const Channel& c : group.channels) {
    if (&c != time_channel) columns.push_back(&c);
  }
  const std::size_t n = group.num_samples();
  std::string out;
  out += name.empty() ? std::string_view("fesbench_trial") : name;
  out += "\nversion=1\nnRows=" + std::to_string(n) +
         "\nnColumns=" + std::to_string(columns.size()) + "\ninDegrees=yes\n";
  for (const auto& [key, value] : metadata) out += key + "=" + value + "\n";
  out += "endheader\n";
  for (std::size_t j = 0; j < columns.size(); ++j) {
    if (j) out += '\t';
    out += columns[j] == time_channel ? std::string("time") : columns[j]->name;
  }
  out += '\n';
  for (std::size_t k = 0; k < n; ++k) {
    for (std::size_t j = 0; j < columns.size(); ++j) {
      if (j) out += '\t';
      if (k < columns[j]->values.size()) AppendNumber(out, columns[j]->values[k]);
    }
    out += '\n';
  }
  return out;
}

std::string TrialToSto(const Trial& trial) {
  return GroupToSto(trial.MainGroup(), trial.name ? *trial.name : "fesbench_trial");
}

// --- JSON ---------------------------------------------------------------------

namespace {

nlohmann::json ChannelsToJson(const std::vector<Channel>& channels) {
  nlohmann::json array = nlohmann::json::array();
  for (const Channel& c : channels) {
    array.push_back({{"name", c.name}, {"unit", c.unit}, {"values", c.values}});
  }
  return array;
}

Status GroupFromJsonInto(const nlohmann::json& json, const std::string& prefix,
                         ChannelGroup& group) {
  if (!json.is_object()) {
    return Status::InvalidArgument("must be an object",
                                   prefix.empty() ? "" : prefix.substr(0, prefix.size() - 1));
  }
  const auto rate = json.find("sample_rate_hz");
  if (rate == json.end()) return Status::InvalidArgument("missing", prefix + "sample_rate_hz");
  if (!rate->is_number()) {
    return Status::InvalidArgument("must be a number", prefix + "sample_rate_hz");
  }
  group.sample_rate_hz = rate->get<double>();
  const auto channels = json.find("channels");
  if (channels == json.end()) return Status::InvalidArgument("missing", prefix + "channels");
  if (!channels->is_array()) {
    return Status::InvalidArgument("must be an array", prefix + "channels");
  }
  for (std::size_t i = 0; i < channels->size(); ++i) {
    const nlohmann::json& c = (*channels)[i];
    const std::string field = prefix + "channels[" + std::to_string(i) + "]";
    if (!c.is_object()) return Status::InvalidArgument("must be an object", field);
    Channel channel;
    const auto name = c.find("name");
    if (name == c.end()) return Status::InvalidArgument("missing", field + ".name");
    if (!name->is_string()) return Status::InvalidArgument("must be a string", field + ".name");
    channel.name = name->get<std::string>();
    const auto unit = c.find("unit");
    if (unit != c.end()) {
      if (!unit->is_string()) return Status::InvalidArgument("must be a string", field + ".unit");
      channel.unit = unit->get<std::string>();
    } else {
      channel.unit = ChannelUnit(channel.name);
    }
    const auto values = c.find("values");
    if (values == c.end()) return Status::InvalidArgument("missing", field + ".values");
    if (!values->is_array()) return Status::InvalidArgument("must be an array", field + ".values");
    channel.values.reserve(values->size());
    for (std::size_t k = 0; k < values->size(); ++k) {
      if (!(*values)[k].is_number()) {
        return Status::InvalidArgument("must be a number",
                                       field + ".values[" + std::to_string(k) + "]");
      }
      channel.values.push_back((*values)[k].get<double>());
    }
    group.channels.push_back(std::move(channel));
  }
  return ValidateChannelGroup(group, prefix);
}

}  // namespace

Result<DeviceCommandLog> DeviceCommandLogFromJson(const nlohmann::json& json) {
  const std::string f = "device_commands.";
  if (!json.is_object()) return Status::InvalidArgument("must be an object", "device_commands");
  DeviceCommandLog log;
  const auto device = json.find("device");
  if (device == json.end() || !device->is_string()) {
    return Status::InvalidArgument("must be a string", f + "device");
  }
  log.device = device->get<std::string>();
  for (const auto& [key, target] : {std::pair{"pulse_rate_hz", &log.pulse_rate_hz},
                                    std::pair{"current_step_ma", &log.current_step_ma}}) {
    const auto v = json.find(key);
    if (v == json.end() || !v->is_number()) {
      return Status::InvalidArgument("must be a number", f + key);
    }
    *target = v->get<double>();
  }
  const auto start = json.find("start_monotonic_ns");
  if (start == json.end() || !start->is_number_integer()) {
    return Status::InvalidArgument("must be an integer", f + "start_monotonic_ns");
  }
  log.start_monotonic_ns = start->get<std::int64_t>();
  for (const auto& [key, target] : {std::pair{"t_s", &log.t_s},
                                    std::pair{"requested_ma", &log.requested_ma},
                                    std::pair{"commanded_ma", &log.commanded_ma}}) {
    const auto v = json.find(key);
    if (v == json.end() || !v->is_array()) {
      return Status::InvalidArgument("must be an array", f + key);
    }
    for (std::size_t k = 0; k < v->size(); ++k) {
      if (!(*v)[k].is_number()) {
        return Status::InvalidArgument("must be a number", f + key + "[" + std::to_string(k) + "]");
      }
      target->push_back((*v)[k].get<double>());
    }
  }
  const auto single = json.find("single_pulse");
  if (single == json.end() || !single->is_array()) {
    return Status::InvalidArgument("must be an array", f + "single_pulse");
  }
  for (std::size_t k = 0; k < single->size(); ++k) {
    if (!(*single)[k].is_boolean()) {
      return Status::InvalidArgument("must be true or false",
                                     f + "single_pulse[" + std::to_string(k) + "]");
    }
    log.single_pulse.push_back((*single)[k].get<bool>());
  }
  if (Status s = ValidateDeviceCommandLog(log); !s.ok()) return s;
  return log;
}

nlohmann::json DeviceCommandLogToJson(const DeviceCommandLog& d) {
  return {{"device", d.device},
          {"pulse_rate_hz", d.pulse_rate_hz},
          {"current_step_ma", d.current_step_ma},
          {"start_monotonic_ns", d.start_monotonic_ns},
          {"t_s", d.t_s},
          {"requested_ma", d.requested_ma},
          {"commanded_ma", d.commanded_ma},
          {"single_pulse", d.single_pulse}};
}

nlohmann::json GroupToJson(const ChannelGroup& group) {
  return {{"sample_rate_hz", group.sample_rate_hz}, {"channels", ChannelsToJson(group.channels)}};
}

nlohmann::json TrialToJson(const Trial& trial) {
  nlohmann::json json = nlohmann::json::object();
  if (trial.id) json["id"] = *trial.id;
  if (trial.name) json["name"] = *trial.name;
  if (trial.kind) json["kind"] = TrialKindName(*trial.kind);
  if (trial.start_time_unix_ms) json["start_time_unix_ms"] = *trial.start_time_unix_ms;
  json["sample_rate_hz"] = trial.sample_rate_hz;
  json["channels"] = ChannelsToJson(trial.channels);
  if (trial.emg) json["emg"] = GroupToJson(*trial.emg);
  if (trial.pulses) {
    json["pulses"] = {{"pulse_rate_hz", trial.pulses->pulse_rate_hz},
                      {"pulse_width_us", trial.pulses->pulse_width_us},
                      {"t_s", trial.pulses->t_s},
                      {"stim_ma", trial.pulses->stim_ma}};
  }
  if (trial.device_commands) json["device_commands"] = DeviceCommandLogToJson(*trial.device_commands);
  return json;
}

Result<Trial> TrialFromJson(const nlohmann::json& json) {
  if (!json.is_object()) return Status::InvalidArgument("a trial must be a JSON object");
  Trial trial;
  if (const auto id = json.find("id"); id != json.end() && !id->is_null()) {
    if (!id->is_number_integer()) return Status::InvalidArgument("must be an integer", "id");
    trial.id = id->get<std::int64_t>();
  }
  if (const auto name = json.find("name"); name != json.end() && !name->is_null()) {
    if (!name->is_string()) return Status::InvalidArgument("must be a string", "name");
    trial.name = name->get<std::string>();
  }
  if (const auto kind = json.find("kind"); kind != json.end() && !kind->is_null()) {
    if (!kind->is_string()) return Status::InvalidArgument("must be a string", "kind");
    trial.kind = ParseTrialKind(kind->get<std::string>());
    if (!trial.kind) {
      return Status::InvalidArgument(
          "unknown trial kind '" + kind->get<std::string>() + "' (GET /api/v1/trial-kinds lists them)",
          "kind");
    }
  }
  if (const auto start = json.find("start_time_unix_ms");
      start != json.end() && !start->is_null()) {
    if (!start->is_number_integer()) {
      return Status::InvalidArgument("must be an integer", "start_time_unix_ms");
    }
    trial.start_time_unix_ms = start->get<std::int64_t>();
  }
  ChannelGroup main;
  if (Status s = GroupFromJsonInto(json, "", main); !s.ok()) return s;
  trial.sample_rate_hz = main.sample_rate_hz;
  trial.channels = std::move(main.channels);
  if (const auto emg = json.find("emg"); emg != json.end() && !emg->is_null()) {
    ChannelGroup group;
    if (Status s = GroupFromJsonInto(*emg, "emg.", group); !s.ok()) return s;
    trial.emg = std::move(group);
  }
  if (const auto pulses = json.find("pulses"); pulses != json.end() && !pulses->is_null()) {
    if (!pulses->is_object()) return Status::InvalidArgument("must be an object", "pulses");
    PulseRecord record;
    for (const auto& [key, target] : {std::pair{"pulse_rate_hz", &record.pulse_rate_hz},
                                      std::pair{"pulse_width_us", &record.pulse_width_us}}) {
      const auto v = pulses->find(key);
      if (v == pulses->end())
        return Status::InvalidArgument("missing", std::string("pulses.") + key);
      if (!v->is_number()) {
        return Status::InvalidArgument("must be a number", std::string("pulses.") + key);
      }
      *target = v->get<double>();
    }
    for (const auto& [key, target] :
         {std::pair{"t_s", &record.t_s}, std::pair{"stim_ma", &record.stim_ma}}) {
      const std::string field = std::string("pulses.") + key;
      const auto v = pulses->find(key);
      if (v == pulses->end()) return Status::InvalidArgument("missing", field);
      if (!v->is_array()) return Status::InvalidArgument("must be an array", field);
      target->reserve(v->size());
      for (std::size_t k = 0; k < v->size(); ++k) {
        if (!(*v)[k].is_number()) {
          return Status::InvalidArgument("must be a number", field + "[" + std::to_string(k) + "]");
        }
        target->push_back((*v)[k].get<double>());
      }
    }
    if (Status s = ValidatePulseRecord(record); !s.ok()) return s;
    trial.pulses = std::move(record);
  }
  if (const auto log = json.find("device_commands"); log != json.end() && !log->is_null()) {
    auto parsed = DeviceCommandLogFromJson(*log);
    if (!parsed.ok()) return parsed.status();
    trial.device_commands = std::move(*parsed);
  }
  if (Status s = ValidateKindOfName(trial); !s.ok()) return s;
  return trial;
}

// --- files --------------------------------------------------------------------

Result<std::string> ReadTextFile(const std::filesystem::path& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    return Status::NotFound(path.string() + ": is a directory");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::NotFound(path.string() + ": cannot open for reading");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) return Status::Unavailable(path.string() + ": read error");
  return std::move(buffer).str();
}

Status WriteTextFile(const std::filesystem::path& path, std::string_view text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return Status::Unavailable(path.string() + ": cannot open for writing");
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  out.close();
  if (!out) return Status::Unavailable(path.string() + ": write error");
  return Status::Ok();
}

Result<Trial> ReadTrialCsvFile(const std::filesystem::path& path, double default_rate_hz) {
  Result<std::string> text = ReadTextFile(path);
  if (!text.ok()) return text.status();
  Result<Trial> trial = TrialFromCsv(*text, default_rate_hz);
  if (!trial.ok()) {
    const Status& s = trial.status();
    return Status(s.code(), path.string() + ": " + s.message(), s.field());
  }
  return trial;
}

model::TrialColumns ToTrialColumns(const Trial& trial) {
  model::TrialColumns c;
  const auto take = [&](std::string_view name, std::vector<double>& dst) {
    if (const std::vector<double>* v = trial.Values(name)) dst = *v;
  };
  take(kTimeChannel, c.t_s);
  take("stim_ma", c.stim_ma);
  take("angle_deg", c.angle_deg);
  take("velocity_deg_s", c.velocity_deg_s);
  take("accel_deg_s2", c.accel_deg_s2);
  take("torque_nm", c.torque_nm);
  take("activation", c.activation);
  return c;
}

}  // namespace fesbench::api
