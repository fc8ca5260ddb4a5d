#pragma once

/// @file
/// A recorded trial as a wire type (docs/ARCHITECTURE.md, data path; docs/API.md): named channels
/// of samples with their units, in CSV, OpenSim Storage (.sto) and JSON form.
///
/// Layout. A trial holds one channel group sampled together at
/// `sample_rate_hz` (200 Hz on the bench: position, torque, acceleration,
/// stimulation, activation). Its time base is the channel `t_s`, required,
/// finite and strictly increasing; every channel of a group has the same
/// number of samples. Signals recorded at another rate — EMG at 1 kHz
/// (docs/ARCHITECTURE.md, units) — go in the optional second group `emg`, which has its own
/// `sample_rate_hz` and its own `t_s` channel on the same clock. Nothing is
/// resampled: identification resamples if and when it needs to. (A 200 Hz
/// EMG envelope may also live in the main group as `emg_mv`.)
///
/// Channel names are lower-case identifiers that end in their unit
/// (`angle_deg`, `torque_nm`, `stim_ma`); `ChannelUnit` derives the unit
/// string from the name, so a CSV header of names carries the units.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/status.h"
#include "api/trial_kind.h"
#include "model/identify_common.h"
#include "model/signal.h"

namespace fesbench::api {

/// The time-base channel every group must hold.
inline constexpr std::string_view kTimeChannel = "t_s";

/// One named channel of samples.
struct Channel {
  std::string name;  ///< e.g. "angle_deg"; [a-z][a-z0-9_]*.
  std::string unit;  ///< e.g. "deg"; see ChannelUnit.
  std::vector<double> values;
  friend bool operator==(const Channel&, const Channel&) = default;
};

/// Channels sampled together at one rate, with a `t_s` time base.
struct ChannelGroup {
  double sample_rate_hz = 200.0;  ///< > 0, nominal rate of the `t_s` channel.
  std::vector<Channel> channels;

  /// The channel called `name`, or nullptr.
  const Channel* Find(std::string_view name) const;
  Channel* Find(std::string_view name);
  /// The values of channel `name`, or nullptr.
  const std::vector<double>* Values(std::string_view name) const;
  /// Adds a channel (unit from ChannelUnit(name)) or replaces the values of
  /// an existing one; returns it. Does not check lengths: see Validate.
  Channel& Set(std::string name, std::vector<double> values);
  /// Samples per channel (that of the first channel; 0 if none).
  std::size_t num_samples() const;

  friend bool operator==(const ChannelGroup&, const ChannelGroup&) = default;
};

/// The stimulation pulses delivered during a trial (docs/MODEL.md, "Pulse timing: one rule"), as
/// the stimulator read them back: what reached the leg, not what was commanded.
/// Times on the trial's `t_s` axis (the bench's pulse clock restarts at the
/// trial's t_s = 0, so grid pulses fall on k / pulse_rate_hz). Predictions on
/// a stored trial replay these pulses. Two parallel columns, like a channel.
struct PulseRecord {
  double pulse_rate_hz = 33.0;    ///< the stimulator's pulse clock, Hz, > 0.
  double pulse_width_us = 300.0;  ///< pulse width, µs, > 0.
  /// Finite, non-decreasing (two pulses may be read back at one instant,
  /// e.g. a single pulse fired at a grid time).
  std::vector<double> t_s;
  std::vector<double> stim_ma;    ///< delivered amplitude, mA, finite, ≥ 0.

  std::size_t size() const { return t_s.size(); }
  /// The pulses as a model pulse train (times unchanged).
  model::PulseTrain Train() const;
  /// Appends one pulse (no check: see ValidatePulseRecord).
  void Append(double t_s_value, double stim_ma_value);

  friend bool operator==(const PulseRecord&, const PulseRecord&) = default;
};

/// What a hardware stimulator was told during a trial, and when (README,
/// "A real stimulator"): one entry per command that set what the device
/// delivers — an amplitude update of a train the device paces itself, a
/// single pulse, or each pulse of a device the host paces. The simulated
/// stimulator has none. Times are the host's monotonic clock, from the
/// trial's start: `start_monotonic_ns` is that clock (CLOCK_MONOTONIC) at
/// the trial's t_s = 0, the same instant as the trial's start_time_unix_ms.
struct DeviceCommandLog {
  std::string device;                 ///< the driver, e.g. "sciencemode2"; not empty.
  double pulse_rate_hz = 0.0;         ///< the device's own pulse rate (1 / its period), > 0.
  double current_step_ma = 0.0;       ///< the device's resolution, > 0.
  std::int64_t start_monotonic_ns = 0;
  /// When each command was handed to the device's serial port, s from the
  /// trial's start; finite, non-decreasing.
  std::vector<double> t_s;
  std::vector<double> requested_ma;   ///< what the control loop asked for, ≥ 0.
  /// What the device was told: requested_ma rounded down to the device's
  /// step (never above the request), ≥ 0.
  std::vector<double> commanded_ma;
  std::vector<bool> single_pulse;     ///< a single pulse (else a train's amplitude or a paced pulse).

  std::size_t size() const { return t_s.size(); }
  friend bool operator==(const DeviceCommandLog&, const DeviceCommandLog&) = default;
};

/// A recorded (or simulated) trial.
struct Trial {
  std::optional<std::int64_t> id;                  ///< storage id, once stored.
  std::optional<std::string> name;                 ///< e.g. "free_swing_passive".
  /// What the trial is (api/trial_kind.h): storage keeps it with the trial
  /// and fills it from the name when a recorder leaves it unset; it must be
  /// the kind the name belongs to.
  std::optional<TrialKind> kind;
  std::optional<std::int64_t> start_time_unix_ms;  ///< wall-clock start, ms since 1970 UTC.
  double sample_rate_hz = 200.0;                   ///< > 0, rate of `channels`.
  std::vector<Channel> channels;                   ///< includes `t_s`.
  std::optional<ChannelGroup> emg;                 ///< EMG at its own rate (1 kHz).
  std::optional<PulseRecord> pulses;               ///< delivered pulses, if recorded.
  std::optional<DeviceCommandLog> device_commands; ///< a hardware stimulator's commands.

  /// The main group's channel called `name`, or nullptr.
  const Channel* FindChannel(std::string_view name) const;
  Channel* FindChannel(std::string_view name);
  /// The main group's values of channel `name`, or nullptr.
  const std::vector<double>* Values(std::string_view name) const;
  /// Adds or replaces a main-group channel (unit from its name).
  Channel& SetChannel(std::string name, std::vector<double> values);
  /// Samples per main-group channel (0 if none).
  std::size_t num_samples() const;

  /// The main channels as a group (copies).
  ChannelGroup MainGroup() const { return {sample_rate_hz, channels}; }

  friend bool operator==(const Trial&, const Trial&) = default;
};

/// The unit a channel name's suffix denotes: "_s" → "s", "_ms" → "ms",
/// "_ma" → "mA", "_deg" → "deg", "_deg_s" → "deg/s", "_deg_s2" → "deg/s^2",
/// "_nm" → "N.m", "_mv" → "mV", "_hz" → "Hz", "_m_s2" → "m/s^2", "_m" → "m";
/// "activation" and names ending
/// in "_gain" → "1" (dimensionless); otherwise "" (unknown).
std::string ChannelUnit(std::string_view name);

/// True if name is a valid channel name: [a-z][a-z0-9_]*, at most 64 chars.
bool IsValidChannelName(std::string_view name);

/// Checks a group: rate finite and > 0, names valid and unique, all channels
/// the same length, `t_s` present, every value finite, `t_s` strictly
/// increasing. The reported field is `<prefix>channels[i]...` (prefix "" or
/// "emg.").
Status ValidateChannelGroup(const ChannelGroup& group, std::string_view field_prefix = {});
/// Checks a pulse record: rate and width finite and > 0, columns of equal
/// length, times finite and non-decreasing, amplitudes finite and ≥ 0.
/// The reported field is "pulses.<name>" (e.g. "pulses.t_s[3]").
Status ValidatePulseRecord(const PulseRecord& pulses);
/// Checks a device command log: device named, rate and step finite and
/// > 0, columns of equal length, times finite and non-decreasing,
/// amplitudes finite and ≥ 0, commanded ≤ requested. Field
/// "device_commands.<name>".
Status ValidateDeviceCommandLog(const DeviceCommandLog& log);
/// Checks the main group and, if present, the EMG group and the pulses, and
/// that a set kind is the kind of a set name (field "kind").
Status ValidateTrial(const Trial& trial);

// --- CSV --------------------------------------------------------------------

/// CSV text of a channel group: a header row of channel names (which carry
/// the units), then one row per sample; numbers in the shortest form that
/// reads back exactly; "\n" line ends. The EMG group, if any, is written as
/// its own CSV with GroupToCsv(*trial.emg).
std::string GroupToCsv(const ChannelGroup& group);
/// CSV text of the trial's main group.
std::string TrialToCsv(const Trial& trial);

/// Parses CSV written by GroupToCsv or by hand. Accepts "\n" or "\r\n", a
/// UTF-8 BOM, spaces around fields and trailing blank lines. Rejects with
/// kInvalidArgument and a message naming line (1-based) and column: an empty
/// file; a missing header row (first line numeric); an empty, invalid or
/// duplicate channel name; no `t_s` column; a row with the wrong number of
/// columns; a blank line between rows; a value that is not a number, NaN or
/// infinite; `t_s` not strictly increasing; fewer than one data row.
/// The sample rate is (N − 1) / (t_last − t_first), or `default_rate_hz`
/// for a single row.
Result<ChannelGroup> GroupFromCsv(std::string_view text, double default_rate_hz = 200.0);
/// GroupFromCsv into a trial's main group (no id, name or start time).
Result<Trial> TrialFromCsv(std::string_view text, double default_rate_hz = 200.0);

// --- OpenSim Storage ----------------------------------------------------------

/// OpenSim Storage (.sto, version 1) text of a group: header lines
/// `<name>`, `version=1`, `nRows=N`, `nColumns=M` (time included),
/// `inDegrees=yes`, `endheader`, then tab-separated rows with the time
/// channel labelled `time` first, then the other channels by name.
/// `metadata` adds `key=value` header lines before `endheader` (keys and
/// values must not contain line breaks).
std::string GroupToSto(const ChannelGroup& group, std::string_view name,
                       const std::vector<std::pair<std::string, std::string>>& metadata = {});
/// The trial's main group as .sto, named trial.name or "fesbench_trial".
std::string TrialToSto(const Trial& trial);

// --- JSON -----------------------------------------------------------------------

/// JSON form:
/// `{"id": 3, "name": "...", "kind": "...", "start_time_unix_ms": ..., "sample_rate_hz": 200,
///   "channels": [{"name": "t_s", "unit": "s", "values": [...]}, ...],
///   "emg": {"sample_rate_hz": 1000, "channels": [...]},
///   "pulses": {"pulse_rate_hz": 33, "pulse_width_us": 300,
///              "t_s": [...], "stim_ma": [...]}}`;
/// absent optionals are omitted. Never fails. (CSV and .sto carry the main
/// group only.)
nlohmann::json TrialToJson(const Trial& trial);
/// A device command log as JSON (the `device_commands` of a trial's JSON,
/// also kept in a BIDS export's sidecar), and back, checked
/// (ValidateDeviceCommandLog; fields "device_commands.<name>").
nlohmann::json DeviceCommandLogToJson(const DeviceCommandLog& log);
Result<DeviceCommandLog> DeviceCommandLogFromJson(const nlohmann::json& json);
nlohmann::json GroupToJson(const ChannelGroup& group);
/// Parses and validates (ValidateTrial) the JSON form; the unit of a channel
/// is optional and defaults to ChannelUnit(name). Errors name the field path,
/// e.g. "channels[2].values[7]".
Result<Trial> TrialFromJson(const nlohmann::json& json);

// --- files --------------------------------------------------------------------

/// Reads a whole text file (kNotFound if it cannot be opened).
Result<std::string> ReadTextFile(const std::filesystem::path& path);
/// Writes a whole text file (kUnavailable if it cannot be written).
Status WriteTextFile(const std::filesystem::path& path, std::string_view text);
/// ReadTextFile + TrialFromCsv; messages are prefixed with the path.
Result<Trial> ReadTrialCsvFile(const std::filesystem::path& path, double default_rate_hz = 200.0);

/// The trial's main channels as identification columns (model/identify_common.h):
/// t_s, stim_ma, angle_deg, velocity_deg_s, accel_deg_s2, torque_nm,
/// activation; a channel the trial lacks stays empty.
model::TrialColumns ToTrialColumns(const Trial& trial);

}  // namespace fesbench::api
