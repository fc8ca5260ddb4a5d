#include "api/bids.h"

#include <edflib.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "api/json_fields.h"
#include "api/trial_import.h"

namespace fesbench::api {
namespace {

using nlohmann::json;

constexpr std::string_view kTrackingSystem = "kneebench";
// The entity of the derivative's exact EMG samples beside their EDF+ copy.
constexpr std::string_view kExactEmg = "_desc-float64";

void AppendNumber(std::string& out, double value) {
  char buffer[32];
  const auto [ptr, ec] = std::to_chars(buffer, buffer + sizeof buffer, value);
  out.append(buffer, ec == std::errc() ? ptr : buffer);
}

// Columns of `channels`, tab-separated, one row per sample, no header.
std::string ValuesTsv(const std::vector<Channel>& channels) {
  std::string out;
  const std::size_t n = channels.empty() ? 0 : channels.front().values.size();
  out.reserve(n * channels.size() * 12);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < channels.size(); ++j) {
      if (j) out += '\t';
      AppendNumber(out, channels[j].values[i]);
    }
    out += '\n';
  }
  return out;
}

// A tab-separated table of strings with a header row.
struct StringTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  std::optional<std::size_t> Column(std::string_view name) const {
    const auto it = std::find(header.begin(), header.end(), name);
    if (it == header.end()) return std::nullopt;
    return static_cast<std::size_t>(it - header.begin());
  }
};

std::vector<std::string> SplitTabs(std::string_view line) {
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  std::vector<std::string> out;
  std::size_t start = 0;
  while (true) {
    const std::size_t end = line.find('\t', start);
    out.emplace_back(line.substr(start, end == std::string_view::npos ? end : end - start));
    if (end == std::string_view::npos) return out;
    start = end + 1;
  }
}

Result<StringTable> ReadStringTable(const std::string& text, const std::string& path) {
  StringTable table;
  std::size_t start = 0;
  std::size_t line_no = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    const std::string_view line(text.data() + start, end - start);
    start = end + 1;
    ++line_no;
    if (line.empty() || line == "\r") continue;
    std::vector<std::string> fields = SplitTabs(line);
    if (table.header.empty()) {
      table.header = std::move(fields);
    } else if (fields.size() != table.header.size()) {
      return Status::InvalidArgument(path + ": line " + std::to_string(line_no) + ": expected " +
                                     std::to_string(table.header.size()) + " columns, found " +
                                     std::to_string(fields.size()));
    } else {
      table.rows.push_back(std::move(fields));
    }
  }
  if (table.header.empty()) return Status::InvalidArgument(path + ": empty file");
  return table;
}

Result<json> ReadJson(const FileMap& files, const std::string& path) {
  const auto it = files.find(path);
  if (it == files.end()) return Status::InvalidArgument("missing file " + path);
  // Client input (an uploaded archive): read strictly.
  Result<json> j = ParseJsonObject(it->second);
  if (!j.ok()) {
    const Status& s = j.status();
    return Status::InvalidArgument(
        path + ": " + (s.field().empty() ? "" : s.field() + ": ") + s.message(), s.field());
  }
  return j;
}

bool EndsWith(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

// BIDS motion channel type, component and description of a channel.
struct MotionChannelInfo {
  std::string_view type;
  std::string_view component;
  std::string_view description;
};

MotionChannelInfo MotionInfo(std::string_view name) {
  if (name == kTimeChannel) return {"LATENCY", "n/a", "time from the trial's start"};
  if (name == "angle_deg") return {"JNTANG", "n/a", "knee angle, 0 = full extension"};
  if (name == "setpoint_deg") return {"JNTANG", "n/a", "the motor's commanded knee angle"};
  if (name == "accel_m_s2") {
    return {"ACCEL", "x",
            "shank accelerometer, tangential axis, positive toward flexion, gravity included"};
  }
  if (name == "velocity_deg_s") return {"MISC", "n/a", "knee angular velocity"};
  if (name == "accel_deg_s2") return {"MISC", "n/a", "knee angular acceleration"};
  if (name == "torque_nm") return {"MISC", "n/a", "knee torque, extension positive"};
  if (name == "stim_ma") return {"MISC", "n/a", "commanded stimulation amplitude"};
  if (name == "stim_delivered_ma") return {"MISC", "n/a", "stimulation amplitude delivered"};
  if (name == "activation") return {"MISC", "n/a", "model activation"};
  if (name == "emg_mv") return {"MISC", "n/a", "EMG envelope"};
  return {"MISC", "n/a", "n/a"};
}

std::string TrackedPoint(std::string_view leg) {
  return leg == "left" ? "LeftKnee" : leg == "right" ? "RightKnee" : "Knee";
}

std::string Units(const Channel& c) { return c.unit.empty() ? "n/a" : c.unit; }
std::string UnitsBack(const std::string& u) { return u == "n/a" ? std::string() : u; }

// A number in a message, as a person reads it (at most 6 significant digits).
std::string FormatNumber(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.6g", v);
  return buffer;
}

// The entities of a BIDS file name ("sub-01_ses-3_task-x_run-4_motion.tsv"):
// key → label, and the suffix.
std::map<std::string, std::string> Entities(std::string_view file_name, std::string* suffix) {
  std::map<std::string, std::string> out;
  const std::size_t dot = file_name.find('.');
  std::string_view stem = file_name.substr(0, dot);
  while (!stem.empty()) {
    const std::size_t us = stem.find('_');
    const std::string_view part = stem.substr(0, us);
    const std::size_t dash = part.find('-');
    if (dash == std::string_view::npos) {
      if (suffix) *suffix = std::string(part);
    } else {
      out[std::string(part.substr(0, dash))] = std::string(part.substr(dash + 1));
    }
    if (us == std::string_view::npos) break;
    stem.remove_prefix(us + 1);
  }
  return out;
}

std::string BaseName(std::string_view path) {
  const std::size_t slash = path.rfind('/');
  return std::string(slash == std::string_view::npos ? path : path.substr(slash + 1));
}

}  // namespace

std::string BidsLabel(std::string_view text) {
  std::string out;
  for (char c : text) {
    if (std::isalnum(static_cast<unsigned char>(c))) out += c;
  }
  return out.empty() ? "x" : out;
}

std::string BidsTaskLabel(std::string_view trial_name) {
  std::string out;
  bool upper = false;
  for (char c : trial_name) {
    if (!std::isalnum(static_cast<unsigned char>(c))) {
      upper = !out.empty();
      continue;
    }
    out += upper ? static_cast<char>(std::toupper(static_cast<unsigned char>(c))) : c;
    upper = false;
  }
  return out.empty() ? "x" : out;
}

ChannelGroup ToOpenSimCoordinates(ChannelGroup group, std::string_view leg) {
  // OpenSim's gait models name the knee coordinate knee_angle_r / _l and
  // count flexion negative (api/trial_import.cc reads them back with the
  // sign turned); fesbench's angle_deg counts flexion positive.
  const std::string coordinate = std::string("knee_angle_") + (leg == "left" ? "l" : "r");
  for (Channel& c : group.channels) {
    if (c.name != "angle_deg" && c.name != "velocity_deg_s") continue;
    c.name = c.name == "angle_deg" ? coordinate : coordinate + "_speed";
    for (double& v : c.values) v = -v;
  }
  return group;
}

std::string TrialToOpenSimMotion(const Trial& trial, std::string_view leg) {
  ChannelGroup knee;
  knee.sample_rate_hz = trial.sample_rate_hz;
  for (std::string_view name :
       {kTimeChannel, std::string_view("angle_deg"), std::string_view("velocity_deg_s")}) {
    if (const Channel* c = trial.FindChannel(name)) knee.channels.push_back(*c);
  }
  if (knee.Find(kTimeChannel) == nullptr) return {};
  return GroupToSto(ToOpenSimCoordinates(std::move(knee), leg),
                    trial.name.value_or("fesbench_trial"));
}

std::optional<std::string> EmgToEdf(const ChannelGroup& emg,
                                    std::optional<std::int64_t> start_time_unix_ms) {
  // EDF+ records hold a whole number of samples: one-second records at an
  // integer rate.
  const double rate = emg.sample_rate_hz;
  if (!(rate >= 1.0) || rate != std::floor(rate) || rate > 1e6) return std::nullopt;
  const int per_record = static_cast<int>(rate);
  std::vector<const Channel*> signals;
  for (const Channel& c : emg.channels) {
    if (c.name != kTimeChannel) signals.push_back(&c);
  }
  if (signals.empty()) return std::nullopt;
  const std::size_t n = emg.num_samples();
  const std::size_t records = std::max<std::size_t>(1, (n + per_record - 1) / per_record);

  // EDFlib writes to a path and keeps its open files in a static table.
  static std::mutex edflib_mutex;
  const std::lock_guard lock(edflib_mutex);
  std::string path = (std::filesystem::temp_directory_path() / "fesbench-emg-XXXXXX").string();
  const int fd = ::mkstemp(path.data());
  if (fd < 0) return std::nullopt;
  ::close(fd);
  struct Remove {
    std::string path;
    ~Remove() { std::remove(path.c_str()); }
  } remove{path};
  const int handle = edfopen_file_writeonly(path.c_str(), EDFLIB_FILETYPE_EDFPLUS,
                                            static_cast<int>(signals.size()));
  if (handle < 0) return std::nullopt;
  bool ok = true;
  for (std::size_t j = 0; j < signals.size(); ++j) {
    const int s = static_cast<int>(j);
    // A symmetric physical range that holds every sample, in three
    // significant digits (the header field has 8 characters).
    double peak = 0.0;
    for (double v : signals[j]->values) peak = std::max(peak, std::abs(v));
    if (!(peak > 0.0) || !std::isfinite(peak)) peak = 1.0;
    const double scale = std::pow(10.0, std::floor(std::log10(peak)) - 2.0);
    peak = std::ceil(peak / scale) * scale;
    ok = ok && edf_set_samplefrequency(handle, s, per_record) == 0 &&
         edf_set_physical_maximum(handle, s, peak) == 0 &&
         edf_set_physical_minimum(handle, s, -peak) == 0 &&
         edf_set_digital_maximum(handle, s, 32767) == 0 &&
         edf_set_digital_minimum(handle, s, -32768) == 0 &&
         edf_set_label(handle, s, signals[j]->name.c_str()) == 0 &&
         edf_set_physical_dimension(handle, s, signals[j]->unit.c_str()) == 0;
  }
  // The trial's start, where EDF can hold it (1985-2084); else the
  // anonymised 1985-01-01 00:00:00.
  int date[6] = {1985, 1, 1, 0, 0, 0};
  if (start_time_unix_ms) {
    const auto t = std::chrono::sys_time<std::chrono::milliseconds>(
        std::chrono::milliseconds(*start_time_unix_ms));
    const auto day = std::chrono::floor<std::chrono::days>(t);
    const std::chrono::year_month_day ymd(day);
    const std::chrono::hh_mm_ss hms(t - day);
    if (static_cast<int>(ymd.year()) >= 1985 && static_cast<int>(ymd.year()) <= 2084) {
      date[0] = static_cast<int>(ymd.year());
      date[1] = static_cast<int>(static_cast<unsigned>(ymd.month()));
      date[2] = static_cast<int>(static_cast<unsigned>(ymd.day()));
      date[3] = static_cast<int>(hms.hours().count());
      date[4] = static_cast<int>(hms.minutes().count());
      date[5] = static_cast<int>(hms.seconds().count());
    }
  }
  ok = ok &&
       edf_set_startdatetime(handle, date[0], date[1], date[2], date[3], date[4], date[5]) == 0;
  ok = ok && edf_set_equipment(handle, "fesbench knee bench") == 0;
  std::vector<double> buffer(static_cast<std::size_t>(per_record));
  for (std::size_t r = 0; ok && r < records; ++r) {
    for (const Channel* c : signals) {
      // The last record padded with zeros.
      for (int k = 0; k < per_record; ++k) {
        const std::size_t i =
            r * static_cast<std::size_t>(per_record) + static_cast<std::size_t>(k);
        buffer[static_cast<std::size_t>(k)] = i < c->values.size() ? c->values[i] : 0.0;
      }
      ok = ok && edfwrite_physical_samples(handle, buffer.data()) == 0;
    }
  }
  ok = edfclose_file(handle) == 0 && ok;
  if (!ok) return std::nullopt;
  std::ifstream in(path, std::ios::binary);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  if (!in) return std::nullopt;
  return std::move(bytes).str();
}

void AddBidsTrial(const Trial& trial, const BidsTrialPlace& place, FileMap& files) {
  const std::string name = trial.name.value_or("trial");
  const std::string dir = "sub-" + place.subject_label + "/ses-" + place.session_label + "/";
  const std::string entities =
      "sub-" + place.subject_label + "_ses-" + place.session_label + "_task-" + BidsTaskLabel(name);
  const std::string run = "_run-" + std::to_string(place.run);
  const std::string motion =
      dir + "motion/" + entities + "_tracksys-" + std::string(kTrackingSystem) + run;
  const std::string derived = std::string(kBidsDerivatives);

  // Channels: t_s first (the LATENCY channel), then the rest in stored order.
  std::vector<Channel> ordered;
  if (const Channel* t = trial.FindChannel(kTimeChannel)) ordered.push_back(*t);
  for (const Channel& c : trial.channels) {
    if (c.name != kTimeChannel) ordered.push_back(c);
  }
  files[motion + "_motion.tsv"] = ValuesTsv(ordered);
  std::string channels = "name\tcomponent\ttype\ttracked_point\tunits\tdescription\n";
  std::map<std::string, int> counts;
  for (const Channel& c : ordered) {
    const MotionChannelInfo info = MotionInfo(c.name);
    ++counts[std::string(info.type)];
    const bool on_knee = info.type != "MISC" || c.name == "velocity_deg_s" ||
                         c.name == "accel_deg_s2" || c.name == "torque_nm";
    channels += c.name + "\t" + std::string(info.component) + "\t" + std::string(info.type) + "\t" +
                (on_knee ? TrackedPoint(place.leg) : "n/a") + "\t" + Units(c) + "\t" +
                std::string(info.description) + "\n";
  }
  files[motion + "_channels.tsv"] = std::move(channels);
  const double duration = trial.num_samples() > 1 ? trial.Values(kTimeChannel)->back() -
                                                        trial.Values(kTimeChannel)->front()
                                                  : 0.0;
  json sidecar = {
      {"TaskName", name},
      {"TaskDescription", "fesbench trial '" + name + "' on the knee bench"},
      {"SamplingFrequency", trial.sample_rate_hz},
      {"TrackingSystemName", "fesbench knee bench"},
      {"MotionChannelCount", ordered.size()},
      {"TrackedPointsCount", 1},
      {"RecordingDuration", duration},
      {"MissingValues", "n/a"},
  };
  for (const auto& [type, count] : counts) sidecar[type + "ChannelCount"] = count;
  files[motion + "_motion.json"] = sidecar.dump(2) + "\n";

  // What no BIDS sidecar field holds, in the derivative (docs/API.md
  // "Session archives"): the trial's id, name and start, the pulse clock,
  // and what a hardware stimulator was told.
  json fesbench = {{"name", name}};
  if (trial.id) fesbench["id"] = *trial.id;
  if (trial.start_time_unix_ms) fesbench["start_time_unix_ms"] = *trial.start_time_unix_ms;
  if (trial.pulses) {
    fesbench["pulses"] = {{"pulse_rate_hz", trial.pulses->pulse_rate_hz},
                          {"pulse_width_us", trial.pulses->pulse_width_us}};
  }
  if (trial.device_commands)
    fesbench["device_commands"] = DeviceCommandLogToJson(*trial.device_commands);
  files[derived + motion + "_trial.json"] = fesbench.dump(2) + "\n";
  files[derived + motion + "_motion.mot"] = TrialToOpenSimMotion(trial, place.leg);

  if (trial.pulses) {
    const PulseRecord& p = *trial.pulses;
    std::string events = "onset\tduration\ttrial_type\tamplitude_ma\twidth_us\n";
    for (std::size_t i = 0; i < p.size(); ++i) {
      AppendNumber(events, p.t_s[i]);
      events += '\t';
      AppendNumber(events, p.pulse_width_us * 1e-6);
      events += "\tstimulation_pulse\t";
      AppendNumber(events, p.stim_ma[i]);
      events += '\t';
      AppendNumber(events, p.pulse_width_us);
      events += '\n';
    }
    files[motion + "_events.tsv"] = std::move(events);
    std::string rate;
    AppendNumber(rate, p.pulse_rate_hz);
    const json events_json = {
        {"onset", {{"Description", "time of the pulse from the trial's start"}, {"Units", "s"}}},
        {"duration", {{"Description", "pulse width"}, {"Units", "s"}}},
        {"trial_type",
         {{"Description", "kind of event"},
          {"Levels",
           {{"stimulation_pulse",
             "one biphasic stimulation pulse as delivered, on a " + rate + " Hz pulse clock"}}}}},
        {"amplitude_ma", {{"Description", "delivered pulse amplitude"}, {"Units", "mA"}}},
        {"width_us", {{"Description", "pulse width"}, {"Units", "us"}}},
    };
    files[motion + "_events.json"] = events_json.dump(2) + "\n";
  }

  if (trial.emg) {
    // BIDS v1.11.0 (BEP042) layout, in the derivative: bids-validator
    // 1.15.0 predates the emg datatype (docs/API.md "Session archives").
    const std::string emg = derived + dir + "emg/" + entities + run;
    std::vector<Channel> emg_ordered;
    if (const Channel* t = trial.emg->Find(kTimeChannel)) emg_ordered.push_back(*t);
    for (const Channel& c : trial.emg->channels) {
      if (c.name != kTimeChannel) emg_ordered.push_back(c);
    }
    std::string rate;
    AppendNumber(rate, trial.emg->sample_rate_hz);
    // The exact samples (lossless float64 text), which an import reads.
    files[emg + std::string(kExactEmg) + "_emg.tsv"] = ValuesTsv(emg_ordered);
    std::string exact_channels = "name\ttype\tunits\tsampling_frequency\tdescription\n";
    std::string edf_channels = "name\ttype\tunits\tsampling_frequency\tdescription\n";
    int emg_count = 0;
    for (const Channel& c : emg_ordered) {
      const bool time = c.name == kTimeChannel;
      const std::string row =
          c.name + "\t" + (time ? "SYSCLOCK" : "EMG") + "\t" + Units(c) + "\t" + rate + "\t" +
          (time ? "time from the trial's start" : "surface EMG, quadriceps") + "\n";
      exact_channels += row;
      if (!time) {
        edf_channels += row;
        ++emg_count;
      }
    }
    files[emg + std::string(kExactEmg) + "_channels.tsv"] = std::move(exact_channels);
    // The BIDS copy: EDF+ (16-bit), the EMG channels without the time base.
    std::optional<std::string> edf = EmgToEdf(*trial.emg, trial.start_time_unix_ms);
    if (edf && emg_count > 0) {
      files[emg + "_emg.edf"] = std::move(*edf);
      files[emg + "_channels.tsv"] = std::move(edf_channels);
      const json emg_json = {
          {"TaskName", name},
          {"SamplingFrequency", trial.emg->sample_rate_hz},
          {"EMGChannelCount", emg_count},
          {"EMGPlacementScheme", "other"},
          {"EMGPlacementSchemeDescription", "surface electrodes over the stimulated quadriceps"},
          {"EMGReference", "bipolar"},
          {"PowerLineFrequency", "n/a"},
          {"SoftwareFilters", "n/a"},
          {"RecordingType", "continuous"},
          {"RecordingDuration", duration},
      };
      files[emg + "_emg.json"] = emg_json.dump(2) + "\n";
    }
  }
}

Result<std::vector<BidsTrial>> ReadBidsTrials(const FileMap& files) {
  std::vector<BidsTrial> out;
  for (const auto& [path, text] : files) {
    if (!EndsWith(path, "_motion.tsv")) continue;
    const std::string prefix = path.substr(0, path.size() - std::string("_motion.tsv").size());
    const auto channels_it = files.find(prefix + "_channels.tsv");
    if (channels_it == files.end()) {
      return Status::InvalidArgument("missing file " + prefix + "_channels.tsv (for " + path + ")");
    }
    Result<StringTable> channels = ReadStringTable(channels_it->second, channels_it->first);
    if (!channels.ok()) return channels.status();
    const auto name_col = channels->Column("name");
    const auto units_col = channels->Column("units");
    if (!name_col || !units_col) {
      return Status::InvalidArgument(channels_it->first + ": needs the columns name and units");
    }
    std::vector<std::string> labels;
    std::vector<std::string> units;
    for (const auto& row : channels->rows) {
      labels.push_back(row[*name_col]);
      units.push_back(UnitsBack(row[*units_col]));
    }
    Result<json> sidecar = ReadJson(files, prefix + "_motion.json");
    if (!sidecar.ok()) return sidecar.status();
    // The trial's own record in the derivative; a dataset from elsewhere
    // has none, and its trials are named by their TaskName.
    const std::string trial_path = std::string(kBidsDerivatives) + prefix + "_trial.json";
    json fes = json::object();
    if (files.contains(trial_path)) {
      Result<json> read = ReadJson(files, trial_path);
      if (!read.ok()) return read.status();
      fes = std::move(*read);
    }
    // Client input: a field of the wrong type is refused, not thrown.
    const json& task = sidecar->contains("TaskName") ? (*sidecar)["TaskName"] : json("");
    const json& own = fes.contains("name") ? fes["name"] : task;
    if (!own.is_string()) {
      return Status::InvalidArgument(
          (fes.contains("name") ? trial_path + ": name" : prefix + "_motion.json: TaskName") +
          " must be a string");
    }
    std::string name = own.get<std::string>();
    if (!sidecar->contains("SamplingFrequency") || !(*sidecar)["SamplingFrequency"].is_number()) {
      return Status::InvalidArgument(prefix + "_motion.json: SamplingFrequency is required");
    }
    // The motion table read exactly as written: identity mapping, the
    // channels' own units, the declared rate.
    Result<TextTable> table = ReadTextTable(text, "tsv", &labels);
    if (!table.ok()) return Status::InvalidArgument(path + ": " + table.status().message());
    if (labels.empty() || labels.front() != kTimeChannel) {
      return Status::InvalidArgument(channels_it->first + ": the first channel must be t_s");
    }
    for (std::size_t j = 0; j < labels.size(); ++j) {
      if (!IsValidChannelName(labels[j])) {
        return Status::InvalidArgument(channels_it->first + ": line " + std::to_string(j + 2) +
                                       ": '" + labels[j] + "' is not a channel name");
      }
      if (units[j] != ChannelUnit(labels[j])) {
        return Status::InvalidArgument(
            channels_it->first + ": line " + std::to_string(j + 2) + ": channel " + labels[j] +
            " is in " + (ChannelUnit(labels[j]).empty() ? "no unit" : ChannelUnit(labels[j])) +
            ", not " + (units[j].empty() ? "n/a" : units[j]) +
            " (an archive's values are in their channel's own unit)");
      }
    }
    // Every check of a recording import (api/trial_import.h): uniform
    // sampling at the declared rate, each value in its channel's physical
    // range, the channels the trial's kind needs. Identity mapping: the
    // values are taken exactly as written.
    ImportSpec spec;
    spec.kind = name;
    spec.format = "tsv";
    spec.sample_rate_hz = (*sidecar)["SamplingFrequency"].get<double>();
    Result<Trial> checked = TrialFromTable(*table, spec);
    if (!checked.ok()) {
      const std::string field(checked.status().field());
      const std::string where = field == "sample_rate_hz"
                                    ? prefix + "_motion.json: SamplingFrequency"
                                : field == "kind" ? prefix + "_motion.json: TaskName"
                                                  : path;
      return Status::InvalidArgument(where + ": " + checked.status().message());
    }
    Trial trial = std::move(*checked);
    trial.name = name;
    if (fes.contains("start_time_unix_ms") && fes["start_time_unix_ms"].is_number_integer()) {
      trial.start_time_unix_ms = fes["start_time_unix_ms"].get<std::int64_t>();
    }
    if (fes.contains("device_commands")) {
      Result<DeviceCommandLog> log = DeviceCommandLogFromJson(fes["device_commands"]);
      if (!log.ok()) {
        return Status::InvalidArgument(trial_path + ": " + std::string(log.status().field()) +
                                       ": " + log.status().message());
      }
      trial.device_commands = std::move(*log);
    }

    // Pulses.
    const auto events_it = files.find(prefix + "_events.tsv");
    if (events_it != files.end()) {
      Result<StringTable> events = ReadStringTable(events_it->second, events_it->first);
      if (!events.ok()) return events.status();
      const auto onset = events->Column("onset");
      const auto amplitude = events->Column("amplitude_ma");
      if (!onset || !amplitude) {
        return Status::InvalidArgument(events_it->first + ": needs onset and amplitude_ma");
      }
      const json clock = fes.value("pulses", json::object());
      if (!clock.is_object() || !clock.contains("pulse_rate_hz") ||
          !clock["pulse_rate_hz"].is_number() || !clock.contains("pulse_width_us") ||
          !clock["pulse_width_us"].is_number()) {
        const std::string what = ": pulses.pulse_rate_hz and pulses.pulse_width_us are required";
        return Status::InvalidArgument(trial_path + what + " beside " + events_it->first);
      }
      PulseRecord pulses;
      pulses.pulse_rate_hz = clock["pulse_rate_hz"].get<double>();
      pulses.pulse_width_us = clock["pulse_width_us"].get<double>();
      for (std::size_t i = 0; i < events->rows.size(); ++i) {
        double t = 0.0;
        double u = 0.0;
        const std::string& ts = events->rows[i][*onset];
        const std::string& us = events->rows[i][*amplitude];
        const auto r1 = std::from_chars(ts.data(), ts.data() + ts.size(), t);
        const auto r2 = std::from_chars(us.data(), us.data() + us.size(), u);
        if (r1.ec != std::errc() || r1.ptr != ts.data() + ts.size() || r2.ec != std::errc() ||
            r2.ptr != us.data() + us.size()) {
          return Status::InvalidArgument(events_it->first + ": line " + std::to_string(i + 2) +
                                         ": onset and amplitude_ma must be numbers");
        }
        // A recording import's range for the stimulation (api/trial_import.h).
        const auto range = ChannelRange("stim_ma");
        if (range && (u < range->first || u > range->second)) {
          return Status::InvalidArgument(events_it->first + ": line " + std::to_string(i + 2) +
                                         ": amplitude_ma " + us + " mA is outside the range of " +
                                         "stim_ma (" + FormatNumber(range->first) + " to " +
                                         FormatNumber(range->second) + " mA)");
        }
        pulses.Append(t, u);
      }
      trial.pulses = std::move(pulses);
    }

    // EMG: the same entities without tracksys, under emg/; the exact
    // samples in the derivative (the EDF+ copy is 16-bit).
    std::string emg_prefix = std::string(kBidsDerivatives) + prefix;
    const std::string motion_dir = "/motion/";
    if (const std::size_t at = emg_prefix.rfind(motion_dir); at != std::string::npos) {
      emg_prefix.replace(at, motion_dir.size(), "/emg/");
    }
    const std::string tracksys = "_tracksys-" + std::string(kTrackingSystem);
    if (const std::size_t at = emg_prefix.find(tracksys); at != std::string::npos) {
      emg_prefix.erase(at, tracksys.size());
    }
    emg_prefix += kExactEmg;
    const auto emg_it = files.find(emg_prefix + "_emg.tsv");
    if (emg_it != files.end()) {
      const auto emg_channels_it = files.find(emg_prefix + "_channels.tsv");
      if (emg_channels_it == files.end()) {
        return Status::InvalidArgument("missing file " + emg_prefix + "_channels.tsv");
      }
      Result<StringTable> ec = ReadStringTable(emg_channels_it->second, emg_channels_it->first);
      if (!ec.ok()) return ec.status();
      const auto en = ec->Column("name");
      const auto eu = ec->Column("units");
      if (!en || !eu) {
        return Status::InvalidArgument(emg_channels_it->first + ": needs name and units");
      }
      std::vector<std::string> emg_labels;
      for (const auto& row : ec->rows) emg_labels.push_back(row[*en]);
      const auto rate_col = ec->Column("sampling_frequency");
      double emg_rate = 0.0;
      if (rate_col && !ec->rows.empty()) {
        const std::string& text_rate = ec->rows.front()[*rate_col];
        const auto r =
            std::from_chars(text_rate.data(), text_rate.data() + text_rate.size(), emg_rate);
        if (r.ec != std::errc() || r.ptr != text_rate.data() + text_rate.size()) emg_rate = 0.0;
      }
      if (!(emg_rate > 0.0)) {
        return Status::InvalidArgument(emg_channels_it->first +
                                       ": sampling_frequency must be a number > 0");
      }
      Result<TextTable> emg_table = ReadTextTable(emg_it->second, "tsv", &emg_labels);
      if (!emg_table.ok()) {
        return Status::InvalidArgument(emg_it->first + ": " + emg_table.status().message());
      }
      // The EMG spans the motion's time (its rate is what makes it so): a
      // wrong sampling_frequency stretches it.
      const double motion_s = static_cast<double>(table->num_rows()) / trial.sample_rate_hz;
      const double emg_s = static_cast<double>(emg_table->num_rows()) / emg_rate;
      if (std::abs(emg_s - motion_s) > 2.0 / trial.sample_rate_hz + 2.0 / emg_rate) {
        return Status::InvalidArgument(
            emg_channels_it->first + ": sampling_frequency " + FormatNumber(emg_rate) +
            " Hz makes the EMG's " + std::to_string(emg_table->num_rows()) + " samples last " +
            FormatNumber(emg_s) + " s; the motion lasts " + FormatNumber(motion_s) + " s");
      }
      ChannelGroup group;
      group.sample_rate_hz = emg_rate;
      for (std::size_t j = 0; j < emg_labels.size(); ++j) {
        const std::string unit = UnitsBack(ec->rows[j][*eu]);
        if (unit != ChannelUnit(emg_labels[j])) {
          return Status::InvalidArgument(emg_channels_it->first + ": line " +
                                         std::to_string(j + 2) + ": channel " + emg_labels[j] +
                                         " is in " + ChannelUnit(emg_labels[j]) + ", not " +
                                         (unit.empty() ? "n/a" : unit));
        }
        if (const auto range = ChannelRange(emg_labels[j])) {
          const std::vector<double>& v = emg_table->columns[j];
          for (std::size_t i = 0; i < v.size(); ++i) {
            if (v[i] < range->first || v[i] > range->second) {
              return Status::InvalidArgument(
                  emg_it->first + ": line " + std::to_string(i + 1) + ", column " +
                  std::to_string(j + 1) + " (" + emg_labels[j] + "): " + FormatNumber(v[i]) +
                  " is outside its range (" + FormatNumber(range->first) + " to " +
                  FormatNumber(range->second) + ")");
            }
          }
        }
        group.channels.push_back({emg_labels[j], unit, std::move(emg_table->columns[j])});
      }
      trial.emg = std::move(group);
    }

    if (Status s = ValidateTrial(trial); !s.ok()) {
      return Status::InvalidArgument(path + ": " + s.message(), s.field());
    }
    BidsTrial bt;
    bt.trial = std::move(trial);
    if (fes.contains("id") && fes["id"].is_number_integer()) {
      bt.original_id = fes["id"].get<std::int64_t>();
    }
    bt.motion_path = path;
    out.push_back(std::move(bt));
  }
  std::stable_sort(out.begin(), out.end(), [](const BidsTrial& a, const BidsTrial& b) {
    return a.original_id.value_or(0) < b.original_id.value_or(0);
  });
  return out;
}

Status ValidateBidsLayout(const FileMap& files) {
  auto missing = [](const std::string& path, const std::string& what) {
    return Status::InvalidArgument(path + ": " + what);
  };
  Result<json> description = ReadJson(files, "dataset_description.json");
  if (!description.ok()) return description.status();
  for (const char* key : {"Name", "BIDSVersion"}) {
    if (!description->contains(key))
      return missing("dataset_description.json", key + std::string(" is required"));
  }
  if (!files.contains("README") && !files.contains("README.md") && !files.contains("README.txt")) {
    return Status::InvalidArgument("README: the dataset's README is required");
  }
  static const std::set<std::string> kMotionTypes = {
      "ACCEL", "ANGACCEL", "GYRO", "JNTANG", "LATENCY", "MAGN", "MISC", "ORNT", "POS", "VEL"};
  int motion_files = 0;
  for (const auto& [path, text] : files) {
    // BIDS EMG is EDF or BDF (BEP042). A derivative's content is its own,
    // but for the EMG files laid out for the BIDS of their time.
    const bool is_emg = EndsWith(path, "_emg.edf") || EndsWith(path, "_emg.bdf");
    if (path.starts_with("derivatives/") && !is_emg) continue;
    const std::string file = BaseName(path);
    std::string suffix;
    const auto entities = Entities(file, &suffix);
    if (file.starts_with("sub-")) {
      for (const auto& [key, label] : entities) {
        if (label.empty() || !std::all_of(label.begin(), label.end(), [](char c) {
              return std::isalnum(static_cast<unsigned char>(c));
            })) {
          return missing(path, "entity " + key + " has label '" + label +
                                   "': labels are letters and digits only");
        }
      }
      if ((suffix == "motion" || suffix == "emg") && !entities.contains("task")) {
        return missing(path, "the task entity is required");
      }
    }
    const bool is_motion = EndsWith(path, "_motion.tsv");
    if (is_motion || is_emg) {
      const std::string data_suffix = is_motion ? "_motion.tsv" : path.substr(path.rfind("_emg"));
      const std::string prefix = path.substr(0, path.size() - data_suffix.size());
      const std::string channels_path = prefix + "_channels.tsv";
      const auto ch = files.find(channels_path);
      if (ch == files.end()) return missing(channels_path, "required beside " + path);
      Result<StringTable> table = ReadStringTable(ch->second, channels_path);
      if (!table.ok()) return table.status();
      const std::vector<std::string> required =
          is_motion
              ? std::vector<std::string>{"name", "component", "type", "tracked_point", "units"}
              : std::vector<std::string>{"name", "type", "units"};
      for (std::size_t k = 0; k < required.size(); ++k) {
        if (table->header.size() <= k || table->header[k] != required[k]) {
          return missing(channels_path,
                         "column " + std::to_string(k + 1) + " must be '" + required[k] + "'");
        }
      }
      const std::size_t type_col = *table->Column("type");
      for (std::size_t r = 0; r < table->rows.size(); ++r) {
        if (is_motion && !kMotionTypes.contains(table->rows[r][type_col])) {
          return missing(channels_path, "line " + std::to_string(r + 2) + ": type '" +
                                            table->rows[r][type_col] +
                                            "' is not a motion channel type");
        }
      }
      if (is_motion) {
        // No header row; every row has one value per channel.
        const std::size_t first_newline = text.find('\n');
        const std::string_view first(
            text.data(), first_newline == std::string::npos ? text.size() : first_newline);
        const std::size_t columns =
            static_cast<std::size_t>(std::count(first.begin(), first.end(), '\t')) + 1;
        if (!text.empty() && columns != table->rows.size()) {
          return missing(path, std::to_string(columns) + " columns but " + channels_path +
                                   " lists " + std::to_string(table->rows.size()) + " channels");
        }
        double first_value = 0.0;
        const std::string_view head = first.substr(0, first.find('\t'));
        const auto r = std::from_chars(head.data(), head.data() + head.size(), first_value);
        if (!text.empty() && (r.ec != std::errc() || r.ptr != head.data() + head.size())) {
          return missing(path, "the first row is not numbers (data files have no header row)");
        }
      }
      const std::string sidecar_path = prefix + (is_motion ? "_motion.json" : "_emg.json");
      Result<json> sidecar = ReadJson(files, sidecar_path);
      if (!sidecar.ok()) return sidecar.status();
      const std::vector<std::string> keys =
          is_motion
              ? std::vector<std::string>{"SamplingFrequency", "TrackingSystemName", "TaskName"}
              : std::vector<std::string>{"EMGPlacementScheme", "EMGReference",
                                         "SamplingFrequency",  "PowerLineFrequency",
                                         "SoftwareFilters",    "TaskName"};
      for (const std::string& key : keys) {
        if (!sidecar->contains(key)) return missing(sidecar_path, key + " is required");
      }
      motion_files += is_motion ? 1 : 0;
    }
    if (EndsWith(path, "_events.tsv")) {
      Result<StringTable> table = ReadStringTable(text, path);
      if (!table.ok()) return table.status();
      if (table->header.size() < 2 || table->header[0] != "onset" ||
          table->header[1] != "duration") {
        return missing(path, "the first columns must be onset and duration");
      }
    }
  }
  if (motion_files == 0) return Status::InvalidArgument("no *_motion.tsv file in the dataset");
  return Status::Ok();
}

}  // namespace fesbench::api
