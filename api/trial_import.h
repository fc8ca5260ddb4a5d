#pragma once

/// @file
/// Recordings made elsewhere, brought in as trials (docs/API.md, "Importing a recording"): a CSV,
/// TSV or OpenSim Storage (.sto) table, a declared trial kind (api/trial_kind.h)
/// and a mapping of its columns onto fesbench channels with the units the
/// file uses. The result is an ordinary api::Trial, which identification and
/// prediction use exactly like a bench trial.
///
/// Checks, each refused with kInvalidArgument naming the line and column of
/// the file (1-based, counting header lines) or the spec field: a malformed
/// header or row, a value that is not a finite number, a time column that is
/// not strictly increasing, sampling that is not uniform (an interval more
/// than 10 % off the median one), a rate outside 20–20000 Hz (a wrong time
/// unit) or one that disagrees with the declared rate by more than 1 %, a value outside its channel's physical range, a mapped column the
/// file lacks, a column neither mapped nor a channel name, and a channel the
/// declared kind needs but the file lacks.

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/status.h"
#include "api/trial.h"

namespace fesbench::api {

/// One column of the file taken into the trial.
struct ImportColumn {
  std::string column;   ///< its label in the file's header.
  std::string channel;  ///< the fesbench channel it becomes, e.g. "angle_deg".
  /// The unit of the file's values, e.g. "rad"; "" means the channel's own
  /// unit (ChannelUnit(channel)), or "rad" for an angle in a .sto file that
  /// says inDegrees=no.
  std::string unit;
  /// The lab's convention: the value taken is sign·scale·(value in the
  /// channel's unit) + offset (offset in the channel's unit), e.g. sign −1
  /// for OpenSim's knee_angle_r (flexion negative), offset 90 for a
  /// goniometer whose zero is the knee hanging.
  int sign = 1;
  double scale = 1.0;
  double offset = 0.0;
  friend bool operator==(const ImportColumn&, const ImportColumn&) = default;
};

/// A column label whose meaning is known (OpenSim's coordinate names): its
/// channel and sign, so `{"column": "knee_angle_r"}` alone maps it.
struct KnownColumn {
  std::string_view column;
  std::string_view channel;
  int sign;
  std::string_view meaning;
};
const std::vector<KnownColumn>& KnownColumns();

/// How to read one recording.
struct ImportSpec {
  std::string kind;            ///< trial kind, also the stored trial's name.
  std::string format = "csv";  ///< "csv", "tsv" or "sto".
  /// The time column's label; "" means "t_s" (csv, tsv) or "time" (sto).
  std::string time_column;
  std::string time_unit = "s";  ///< "s", "ms" or "us".
  /// The nominal rate the recording was made at, Hz; when given the time
  /// column must agree within 1 %, and it becomes the trial's rate.
  std::optional<double> sample_rate_hz;
  std::vector<ImportColumn> columns;  ///< explicit mappings.
  std::vector<std::string> ignore;    ///< columns to leave out.
  /// Columns neither mapped, ignored nor named as a channel with a unit
  /// (e.g. the 22 other coordinates of an OpenSim .mot): refused naming
  /// them (false, the default) or left out (true, `"unmapped": "ignore"`).
  /// Never stored as unit-less channels.
  bool ignore_unmapped = false;
  std::optional<std::int64_t> start_time_unix_ms;
  std::string source;  ///< where it came from (file, rig, lab): kept as provenance.
  /// The mechanical stops of the rig that recorded it, deg (min < max, in
  /// −30…180): free-swing predictions of the trial stop there. Unset: the
  /// knee was free (a pendulum test), predictions have no stops.
  std::optional<std::pair<double, double>> stops_deg;
  friend bool operator==(const ImportSpec&, const ImportSpec&) = default;
};

/// Parses the JSON form (the `spec` of POST /sessions/{id}/trials):
/// `{"kind": "free_swing_passive", "format": "sto", "time_column": "time",
///   "time_unit": "s", "sample_rate_hz": 100,
///   "columns": [{"column": "knee_angle_r", "channel": "angle_deg", "unit": "rad",
///                "sign": -1, "scale": 1, "offset": 0}],
///   "ignore": ["pelvis_tx"], "unmapped": "ignore", "start_time_unix_ms": 1732400000000,
///   "source": "gait lab, Vicon"}`. Errors name the field, e.g. "columns[1].unit".
Result<ImportSpec> ImportSpecFromJson(const nlohmann::json& json);
nlohmann::json ImportSpecToJson(const ImportSpec& spec);

/// The factor that turns a value in `from` into one in `to` (both unit
/// strings as ChannelUnit gives them, with common spellings: "rad", "ms",
/// "us", "µs", "N.mm", "N.cm", "Nm", "A", "uA", "V", "uV", "rad/s",
/// "rad/s^2", "g", "mm", "cm", "%"); nullopt if there is no such conversion.
std::optional<double> UnitFactor(std::string_view from, std::string_view to);

/// Reads `text` as `spec` says and returns the trial (name = spec.kind,
/// units converted, validated with ValidateTrial and the kind's channels).
Result<Trial> ImportTrialText(std::string_view text, const ImportSpec& spec);

/// A delimited text table as read, before any mapping: column labels and
/// values, with the file's line numbers for messages.
struct TextTable {
  std::vector<std::string> labels;
  std::vector<std::vector<double>> columns;  ///< columns[j][i]: row i of column j.
  std::size_t first_data_line = 2;           ///< 1-based line of row 0.
  bool in_degrees = true;                    ///< a .sto header's inDegrees (true elsewhere).
  std::size_t num_rows() const { return columns.empty() ? 0 : columns.front().size(); }
};

/// Reads CSV (`format` "csv"), TSV ("tsv") or OpenSim Storage ("sto"): a
/// header row of labels (or, when `labels` is given, no header row and
/// these labels: BIDS motion files), then rows of numbers. Accepts a UTF-8
/// BOM, "\r\n", spaces around fields and trailing blank lines. Errors name
/// line and column.
Result<TextTable> ReadTextTable(std::string_view text, std::string_view format,
                                const std::vector<std::string>* labels = nullptr);

/// Maps a read table onto a trial as `spec` says (ImportTrialText after
/// reading).
Result<Trial> TrialFromTable(const TextTable& table, const ImportSpec& spec);

/// The physical range a channel's values must lie in (after conversion),
/// or nullopt for channels without one. E.g. angle_deg −90…270 deg,
/// stim_ma 0…200 mA, torque_nm ±1000 N·m.
std::optional<std::pair<double, double>> ChannelRange(std::string_view channel);

}  // namespace fesbench::api
