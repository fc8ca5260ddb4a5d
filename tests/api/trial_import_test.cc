#include "api/trial_import.h"

#include <gtest/gtest.h>

#include <functional>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <numbers>
#include <sstream>
#include <string>

#include "api/bids.h"
#include "api/trial_kind.h"

namespace fesbench::api {
namespace {

// A 200 Hz free swing in the file's own words: time in ms, angle in rad.
std::string SwingCsv(int rows = 5) {
  std::string csv = "time_ms,knee (rad),stim\n";
  for (int i = 0; i < rows; ++i) {
    csv += std::to_string(i * 5) + "," + std::to_string(1.0 + 0.01 * i) + ",0\n";
  }
  return csv;
}

ImportSpec SwingSpec() {
  ImportSpec spec;
  spec.kind = "free_swing_passive";
  spec.time_column = "time_ms";
  spec.time_unit = "ms";
  spec.columns = {{"knee (rad)", "angle_deg", "rad"}, {"stim", "stim_ma", ""}};
  return spec;
}

Status ImportError(std::string_view text, const ImportSpec& spec) {
  auto trial = ImportTrialText(text, spec);
  EXPECT_FALSE(trial.ok());
  return trial.ok() ? Status::Ok() : trial.status();
}

TEST(TrialKindTest, ExactAndFamilyNames) {
  EXPECT_EQ(FindTrialKind("free_swing_passive")->name, "free_swing_passive");
  EXPECT_EQ(FindTrialKind("passive_simultaneous_3")->name, "passive_simultaneous");
  EXPECT_EQ(FindTrialKind("active_random_binary_rb1")->name, "active_random_binary");
  EXPECT_EQ(FindTrialKind("rapid_release_hold_flexion")->name, "rapid_release_hold_flexion");
  EXPECT_EQ(TrialKindOf("passive_simultaneous_2"), TrialKind::kPassiveSimultaneous);
  EXPECT_TRUE(FindTrialKind("passive_positions")->motor);
  EXPECT_FALSE(FindTrialKind("free_swing_passive")->motor);
  EXPECT_EQ(FindTrialKind("prediction_random_binary")->name, "prediction_random_binary");
  EXPECT_EQ(FindTrialKind("free_swing"), nullptr);
  EXPECT_EQ(FindTrialKind("passive_simultaneous_"), nullptr);
  EXPECT_EQ(FindTrialKind("passive_simultaneous_X"), nullptr);
  const Status s = ValidateTrialKindName("walking", "kind");
  EXPECT_EQ(s.field(), "kind");
  EXPECT_NE(s.message().find("free_swing_passive"), std::string::npos);
}

TEST(UnitFactorTest, EveryDeclaredConversion) {
  const double deg = 180.0 / std::numbers::pi;
  EXPECT_DOUBLE_EQ(*UnitFactor("rad", "deg"), deg);
  EXPECT_DOUBLE_EQ(*UnitFactor("rad/s", "deg/s"), deg);
  EXPECT_DOUBLE_EQ(*UnitFactor("rad/s^2", "deg/s^2"), deg);
  EXPECT_DOUBLE_EQ(*UnitFactor("ms", "s"), 1e-3);
  EXPECT_DOUBLE_EQ(*UnitFactor("us", "s"), 1e-6);
  EXPECT_DOUBLE_EQ(*UnitFactor("µs", "s"), 1e-6);
  EXPECT_DOUBLE_EQ(*UnitFactor("N.mm", "N.m"), 1e-3);
  EXPECT_DOUBLE_EQ(*UnitFactor("N.cm", "N.m"), 1e-2);
  EXPECT_DOUBLE_EQ(*UnitFactor("Nm", "N.m"), 1.0);
  EXPECT_DOUBLE_EQ(*UnitFactor("A", "mA"), 1e3);
  EXPECT_DOUBLE_EQ(*UnitFactor("uA", "mA"), 1e-3);
  EXPECT_DOUBLE_EQ(*UnitFactor("V", "mV"), 1e3);
  EXPECT_DOUBLE_EQ(*UnitFactor("uV", "mV"), 1e-3);
  EXPECT_DOUBLE_EQ(*UnitFactor("g", "m/s^2"), 9.80665);
  EXPECT_DOUBLE_EQ(*UnitFactor("mm", "m"), 1e-3);
  EXPECT_DOUBLE_EQ(*UnitFactor("%", "1"), 1e-2);
  EXPECT_FALSE(UnitFactor("rad", "N.m"));
  EXPECT_FALSE(UnitFactor("furlong", "m"));
}

TEST(TrialImportTest, ConvertsTimeAndAngleUnits) {
  auto trial = ImportTrialText(SwingCsv(), SwingSpec());
  ASSERT_TRUE(trial.ok()) << trial.status().ToString();
  EXPECT_EQ(trial->name, "free_swing_passive");
  EXPECT_DOUBLE_EQ(trial->sample_rate_hz, 200.0);
  EXPECT_DOUBLE_EQ((*trial->Values("t_s"))[4], 0.020);
  EXPECT_NEAR((*trial->Values("angle_deg"))[1], 1.01 * 180.0 / std::numbers::pi, 1e-12);
  EXPECT_EQ(trial->FindChannel("angle_deg")->unit, "deg");
  EXPECT_EQ(trial->FindChannel("stim_ma")->unit, "mA");
}

TEST(TrialImportTest, TorqueInNewtonMillimetresAndMicrosecondTime) {
  ImportSpec spec;
  spec.kind = "isometric_ramp_irc";
  spec.time_column = "t";
  spec.time_unit = "us";
  spec.format = "tsv";
  spec.columns = {{"tau", "torque_nm", "N.mm"}, {"I", "stim_ma", "A"}};
  const std::string tsv = "t\ttau\tI\n0\t1500\t0.010\n10000\t2500\t0.020\n20000\t3500\t0.030\n";
  auto trial = ImportTrialText(tsv, spec);
  ASSERT_TRUE(trial.ok()) << trial.status().ToString();
  EXPECT_DOUBLE_EQ(trial->sample_rate_hz, 100.0);
  EXPECT_DOUBLE_EQ((*trial->Values("torque_nm"))[2], 3.5);
  EXPECT_DOUBLE_EQ((*trial->Values("stim_ma"))[1], 20.0);
}

TEST(TrialImportTest, OpenSimStorageInRadians) {
  ImportSpec spec;
  spec.kind = "free_swing_passive";
  spec.format = "sto";
  spec.columns = {{"knee_angle_r", "angle_deg", ""}};
  spec.ignore = {"pelvis_tx"};
  const std::string sto =
      "swing\nversion=1\nnRows=3\nnColumns=3\ninDegrees=no\nendheader\n"
      "time\tknee_angle_r\tpelvis_tx\n0\t1\t0\n0.01\t1.1\t0\n0.02\t1.2\t0\n";
  auto trial = ImportTrialText(sto, spec);
  ASSERT_TRUE(trial.ok()) << trial.status().ToString();
  EXPECT_NEAR((*trial->Values("angle_deg"))[0], 180.0 / std::numbers::pi, 1e-12);
  EXPECT_EQ(trial->FindChannel("pelvis_tx"), nullptr);
}

// A lab's .mot as OpenSim writes it: 24 coordinates in degrees, knee
// flexion negative. The known label alone maps it with its sign; the other
// coordinates are refused by name unless the spec says to ignore them, and
// are never stored.
TEST(TrialImportTest, AnOpenSimMotionInItsOwnConventions) {
  std::string mot = "pendulum\nversion=1\nnRows=3\nnColumns=4\ninDegrees=yes\nendheader\n"
                    "time\tpelvis_tilt\tknee_angle_r\thip_flexion_r\n";
  for (int i = 0; i < 3; ++i) {
    mot += std::to_string(0.01 * i) + "\t2\t" + std::to_string(-5.0 - 10.0 * i) + "\t3\n";
  }
  auto spec = ImportSpecFromJson({{"kind", "free_swing_passive"},
                                  {"format", "sto"},
                                  {"columns", {{{"column", "knee_angle_r"}}}}});
  ASSERT_TRUE(spec.ok()) << spec.status().ToString();
  EXPECT_EQ(spec->columns[0].channel, "angle_deg");
  EXPECT_EQ(spec->columns[0].sign, -1);
  const Status refused = ImportError(mot, *spec);
  EXPECT_EQ(refused.field(), "columns");
  EXPECT_NE(refused.message().find("'pelvis_tilt'"), std::string::npos) << refused.ToString();
  EXPECT_NE(refused.message().find("unmapped"), std::string::npos) << refused.ToString();

  spec->ignore_unmapped = true;
  auto trial = ImportTrialText(mot, *spec);
  ASSERT_TRUE(trial.ok()) << trial.status().ToString();
  // Flexion negative in the file, positive here:
  // −(−5) = 5°, −(−25) = 25°.
  EXPECT_DOUBLE_EQ((*trial->Values("angle_deg"))[0], 5.0);
  EXPECT_DOUBLE_EQ((*trial->Values("angle_deg"))[2], 25.0);
  EXPECT_EQ(trial->channels.size(), 2u);  // t_s and angle_deg: nothing unit-less
  // Written back, the spec keeps the lab's conventions.
  const nlohmann::json j = ImportSpecToJson(*spec);
  EXPECT_EQ(j["unmapped"], "ignore");
  EXPECT_EQ(j["columns"][0]["sign"], -1);
  EXPECT_EQ(ImportSpecFromJson(j).value(), *spec);
}

// sign, scale and offset: a goniometer whose zero is the knee hanging at 90°
// and which reads extension positive, in radians.
TEST(TrialImportTest, SignScaleAndOffsetPerColumn) {
  const std::string csv = "t_s,gonio,stim_ma\n0,0,0\n0.005,0.5,0\n0.01,1,0\n";
  auto spec = ImportSpecFromJson({{"kind", "free_swing_passive"},
                                  {"columns",
                                   {{{"column", "gonio"},
                                     {"channel", "angle_deg"},
                                     {"unit", "rad"},
                                     {"sign", -1},
                                     {"scale", 1.0},
                                     {"offset", 90.0}}}}});
  ASSERT_TRUE(spec.ok()) << spec.status().ToString();
  auto trial = ImportTrialText(csv, *spec);
  ASSERT_TRUE(trial.ok()) << trial.status().ToString();
  EXPECT_DOUBLE_EQ((*trial->Values("angle_deg"))[0], 90.0);
  EXPECT_NEAR((*trial->Values("angle_deg"))[2], 90.0 - 180.0 / std::numbers::pi, 1e-12);
  for (const auto& [key, value] : std::vector<std::pair<std::string, nlohmann::json>>{
           {"sign", 2}, {"sign", "-"}, {"scale", 0}, {"scale", -1}, {"offset", "ninety"}}) {
    auto bad = ImportSpecFromJson(
        {{"kind", "free_swing_passive"},
         {"columns", {{{"column", "gonio"}, {"channel", "angle_deg"}, {key, value}}}}});
    ASSERT_FALSE(bad.ok()) << key;
    EXPECT_EQ(bad.status().field(), "columns[0]." + key);
  }
  EXPECT_EQ(ImportSpecFromJson({{"kind", "free_swing_passive"}, {"unmapped", "keep"}})
                .status()
                .field(),
            "unmapped");
}

TEST(TrialImportTest, MalformedFilesNameThePlace) {
  const ImportSpec spec = SwingSpec();
  // Wrong header: the time column is missing.
  Status s = ImportError("t,knee (rad),stim\n0,1,0\n5,1,0\n", spec);
  EXPECT_EQ(s.field(), "time_column");
  EXPECT_NE(s.message().find("'time_ms'"), std::string::npos) << s.message();
  // No header at all.
  s = ImportError("0,1,0\n5,1,0\n", spec);
  EXPECT_NE(s.message().find("line 1"), std::string::npos) << s.message();
  // Non-monotonic time, on line 4.
  s = ImportError("time_ms,knee (rad),stim\n0,1,0\n5,1,0\n5,1,0\n", spec);
  EXPECT_NE(s.message().find("line 4, column 1 (time_ms)"), std::string::npos) << s.message();
  // NaN on line 3, column 2.
  s = ImportError("time_ms,knee (rad),stim\n0,1,0\n5,nan,0\n10,1,0\n", spec);
  EXPECT_NE(s.message().find("line 3, column 2 (knee (rad))"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("not a finite number"), std::string::npos);
  // Not a number.
  s = ImportError("time_ms,knee (rad),stim\n0,1,0\n5,abc,0\n", spec);
  EXPECT_NE(s.message().find("line 3, column 2"), std::string::npos) << s.message();
  // A short row.
  s = ImportError("time_ms,knee (rad),stim\n0,1,0\n5,1\n", spec);
  EXPECT_NE(s.message().find("line 3: expected 3 columns, found 2"), std::string::npos);
  // Uneven sampling: a gap on line 5.
  s = ImportError("time_ms,knee (rad),stim\n0,1,0\n5,1,0\n10,1,0\n30,1,0\n35,1,0\n", spec);
  EXPECT_NE(s.message().find("line 5, column 1 (time_ms)"), std::string::npos) << s.message();
  // A declared rate the time column contradicts (seconds declared as ms).
  ImportSpec wrong_rate = spec;
  wrong_rate.sample_rate_hz = 1000.0;
  s = ImportError(SwingCsv(), wrong_rate);
  EXPECT_EQ(s.field(), "sample_rate_hz");
  EXPECT_NE(s.message().find("200 Hz"), std::string::npos) << s.message();
  // Milliseconds read as seconds: 0.2 Hz is no rate a bench records at.
  ImportSpec seconds = spec;
  seconds.time_unit = "s";
  s = ImportError(SwingCsv(), seconds);
  EXPECT_EQ(s.field(), "time_unit");
  EXPECT_NE(s.message().find("0.2 Hz"), std::string::npos) << s.message();
  // A missing channel the kind needs.
  ImportSpec irc = spec;
  irc.kind = "isometric_ramp_irc";
  irc.columns = {{"stim", "stim_ma", ""}};
  irc.ignore = {"knee (rad)"};
  s = ImportError(SwingCsv(), irc);
  EXPECT_EQ(s.field(), "columns");
  EXPECT_NE(s.message().find("missing channel torque_nm"), std::string::npos) << s.message();
  // A mapped column the file lacks.
  ImportSpec absent = spec;
  absent.columns.push_back({"torque", "torque_nm", ""});
  s = ImportError(SwingCsv(), absent);
  EXPECT_EQ(s.field(), "columns[2].column");
  // An unmapped column that is no channel name.
  ImportSpec unmapped = spec;
  unmapped.columns.erase(unmapped.columns.begin());
  s = ImportError(SwingCsv(), unmapped);
  EXPECT_NE(s.message().find("column 2 'knee (rad)'"), std::string::npos) << s.message();
  // A unit that cannot be converted.
  ImportSpec bad_unit = spec;
  bad_unit.columns[0].unit = "kg";
  s = ImportError(SwingCsv(), bad_unit);
  EXPECT_EQ(s.field(), "columns[0].unit");
  // Degrees declared where radians were recorded: out of range, named.
  ImportSpec as_degrees = spec;
  as_degrees.columns[0].unit = "";
  s = ImportError("time_ms,knee (rad),stim\n0,1,0\n5,400,0\n", as_degrees);
  EXPECT_NE(s.message().find("line 3, column 2 (knee (rad))"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("outside the range of angle_deg"), std::string::npos);
  // An empty file, and a .sto without its header end.
  EXPECT_NE(ImportError("", spec).message().find("empty"), std::string::npos);
  ImportSpec sto = spec;
  sto.format = "sto";
  EXPECT_NE(ImportError("name\nversion=1\n", sto).message().find("endheader"), std::string::npos);
}

TEST(TrialImportTest, SpecFromJsonNamesFields) {
  auto spec = ImportSpecFromJson(nlohmann::json::parse(
      R"({"kind": "free_swing_passive", "format": "sto", "time_unit": "ms",
          "columns": [{"column": "knee", "channel": "angle_deg", "unit": "rad"}],
          "ignore": ["x"], "sample_rate_hz": 100, "source": "gait lab"})"));
  ASSERT_TRUE(spec.ok()) << spec.status().ToString();
  EXPECT_EQ(spec->columns.front().unit, "rad");
  auto back = ImportSpecFromJson(ImportSpecToJson(*spec));
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(*back, *spec);
  EXPECT_EQ(ImportSpecFromJson(nlohmann::json::parse(R"({"format": "csv"})")).status().field(),
            "kind");
  EXPECT_EQ(ImportSpecFromJson(nlohmann::json::parse(R"({"kind": "walk"})")).status().field(),
            "kind");
  EXPECT_EQ(
      ImportSpecFromJson(
          nlohmann::json::parse(
              R"({"kind": "free_swing_passive", "columns": [{"column": "a", "channel": "A b"}]})"))
          .status()
          .field(),
      "columns[0].channel");
  EXPECT_EQ(ImportSpecFromJson(
                nlohmann::json::parse(R"({"kind": "free_swing_passive", "sample_rate_hz": -3})"))
                .status()
                .field(),
            "sample_rate_hz");
  EXPECT_EQ(ImportSpecFromJson(nlohmann::json::parse(R"({"kind": "free_swing_passive", "x": 1})"))
                .status()
                .field(),
            "x");
}

// A trial as the bench stores it: every channel kind, EMG, pulses.
Trial BenchLikeTrial() {
  Trial t;
  t.id = 41;
  t.name = "active_random_binary_rb1";
  t.start_time_unix_ms = 1732400000123;
  t.sample_rate_hz = 200.0;
  std::vector<double> time, angle, torque, stim, accel;
  for (int i = 0; i < 400; ++i) {
    time.push_back(i / 200.0);
    angle.push_back(90.0 + 20.0 * std::sin(0.1 * i) + 1e-9 / 3.0);
    torque.push_back(0.1 * std::cos(0.37 * i));
    stim.push_back(i % 50 < 25 ? 30.25 : 0.0);
    accel.push_back(0.07239000000000001 * i);
  }
  t.SetChannel("t_s", time);
  t.SetChannel("angle_deg", angle);
  t.SetChannel("torque_nm", torque);
  t.SetChannel("stim_ma", stim);
  t.SetChannel("accel_m_s2", accel);
  ChannelGroup emg;
  emg.sample_rate_hz = 1000.0;
  std::vector<double> et, ev;
  for (int i = 0; i < 2000; ++i) {
    et.push_back(i / 1000.0);
    ev.push_back(0.01 * std::sin(1.3 * i));
  }
  emg.Set("t_s", et);
  emg.Set("emg_mv", ev);
  t.emg = emg;
  PulseRecord pulses;
  for (int k = 0; k < 60; ++k) pulses.Append(k / 33.0, k % 3 ? 30.25 : 0.0);
  t.pulses = pulses;
  return t;
}

TEST(BidsTest, TrialReadsBackBitForBit) {
  const Trial trial = BenchLikeTrial();
  FileMap files;
  AddBidsTrial(trial, {"S01", "3", "right", 41}, files);
  const std::string motion =
      "sub-S01/ses-3/motion/sub-S01_ses-3_task-activeRandomBinaryRb1_tracksys-kneebench_run-41";
  ASSERT_TRUE(files.contains(motion + "_motion.tsv"));
  ASSERT_TRUE(files.contains(motion + "_channels.tsv"));
  ASSERT_TRUE(files.contains(motion + "_events.tsv"));
  // The EMG in the derivative: exact samples, and the EDF+ copy beside them.
  const std::string emg =
      "derivatives/fesbench/sub-S01/ses-3/emg/sub-S01_ses-3_task-activeRandomBinaryRb1_run-41";
  ASSERT_TRUE(files.contains(emg + "_desc-float64_emg.tsv"));
  ASSERT_TRUE(files.contains(emg + "_emg.edf"));
  ASSERT_TRUE(files.contains(emg + "_emg.json"));
  // Nothing of fesbench's own in the BIDS sidecars.
  for (const auto& [path, text] : files) {
    if (path.starts_with("sub-") && path.ends_with(".json")) {
      EXPECT_EQ(text.find("Fesbench"), std::string::npos) << path;
      EXPECT_EQ(text.find("PulseRate"), std::string::npos) << path;
    }
  }
  auto read = ReadBidsTrials(files);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ASSERT_EQ(read->size(), 1u);
  Trial expected = trial;
  expected.id.reset();
  EXPECT_EQ(read->front().trial, expected);
  EXPECT_EQ(read->front().original_id, 41);
}

// docs/API.md, "Session archives": every file of an archive goes through a
// recording import's checks, refused naming the file (and line and column).
TEST(BidsTest, AnArchiveGetsTheChecksOfARecording) {
  const std::string motion =
      "sub-S01/ses-3/motion/sub-S01_ses-3_task-activeRandomBinaryRb1_tracksys-kneebench_run-41";
  const std::string emg =
      "derivatives/fesbench/sub-S01/ses-3/emg/sub-S01_ses-3_task-activeRandomBinaryRb1_run-41";
  const auto refusal = [&](const std::function<void(FileMap&)>& spoil) {
    FileMap files;
    AddBidsTrial(BenchLikeTrial(), {"S01", "3", "right", 41}, files);
    spoil(files);
    auto read = ReadBidsTrials(files);
    EXPECT_FALSE(read.ok());
    return read.ok() ? std::string() : std::string(read.status().message());
  };
  const auto replace = [](std::string& text, const std::string& from, const std::string& to) {
    const std::size_t at = text.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
  };
  // The sidecar says 100 Hz for 200 Hz data.
  std::string m = refusal([&](FileMap& f) {
    replace(f[motion + "_motion.json"], "\"SamplingFrequency\": 200", "\"SamplingFrequency\": 100");
  });
  EXPECT_NE(m.find("_motion.json: SamplingFrequency"), std::string::npos) << m;
  EXPECT_NE(m.find("200 Hz"), std::string::npos) << m;
  // An angle of 5000°: the file, its line and column.
  m = refusal([&](FileMap& f) {
    std::string& tsv = f[motion + "_motion.tsv"];
    const std::size_t line3 = tsv.find('\n', tsv.find('\n') + 1) + 1;
    const std::size_t tab = tsv.find('\t', line3) + 1;
    tsv.replace(tab, tsv.find('\t', tab) - tab, "5000");
  });
  EXPECT_NE(m.find(motion + "_motion.tsv: line 3, column 2 (angle_deg): 5000 deg"),
            std::string::npos)
      << m;
  // angle_deg relabelled rad without conversion.
  m = refusal([&](FileMap& f) { replace(f[motion + "_channels.tsv"], "\tdeg\t", "\trad\t"); });
  EXPECT_NE(m.find("channel angle_deg is in deg, not rad"), std::string::npos) << m;
  // A 5000 mA pulse.
  m = refusal([&](FileMap& f) { replace(f[motion + "_events.tsv"], "30.25", "5000"); });
  EXPECT_NE(m.find("_events.tsv: line"), std::string::npos) << m;
  EXPECT_NE(m.find("5000 mA is outside the range of stim_ma"), std::string::npos) << m;
  // A wrong EMG rate.
  m = refusal([&](FileMap& f) {
    std::string& channels = f[emg + "_desc-float64_channels.tsv"];
    replace(channels, "\t1000\t", "\t2000\t");
  });
  EXPECT_NE(m.find("sampling_frequency 2000 Hz makes the EMG's 2000 samples last 1 s"),
            std::string::npos)
      << m;
}

TEST(BidsTest, AHardwareStimulatorsCommandsReadBackBitForBit) {
  Trial trial = BenchLikeTrial();
  const DeviceCommandLog log{.device = "sciencemode2",
                             .pulse_rate_hz = 1000.0 / 30.5,
                             .current_step_ma = 1.0,
                             .start_monotonic_ns = 4242424242424,
                             .t_s = {0.0, 1.0 / 3.0, 0.7},
                             .requested_ma = {30.25, 0.0, 17.9},
                             .commanded_ma = {30.0, 0.0, 17.0},
                             .single_pulse = {false, false, true}};
  trial.device_commands = log;
  FileMap files;
  AddBidsTrial(trial, {"S01", "3", "right", 41}, files);
  auto read = ReadBidsTrials(files);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ASSERT_EQ(read->size(), 1u);
  ASSERT_TRUE(read->front().trial.device_commands);
  EXPECT_EQ(*read->front().trial.device_commands, log);
  // A trial record whose log does not hold is refused naming the file and field.
  const std::string record =
      "derivatives/fesbench/sub-S01/ses-3/motion/"
      "sub-S01_ses-3_task-activeRandomBinaryRb1_tracksys-kneebench_run-41_trial.json";
  auto json = nlohmann::json::parse(files.at(record));
  json["device_commands"]["commanded_ma"][2] = 18.0;
  files[record] = json.dump();
  auto bad = ReadBidsTrials(files);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find(record + ": device_commands.commanded_ma[2]"),
            std::string::npos)
      << bad.status().message();
  // Fields of the wrong type are refused naming the file, never thrown; a
  // pulse table needs the pulse clock beside it.
  for (const auto& [field, value] :
       std::vector<std::pair<std::string, nlohmann::json>>{{"name", 5}, {"pulses", "33 Hz"}}) {
    FileMap broken = files;
    auto j = nlohmann::json::parse(files.at(record));
    j.erase("device_commands");
    j[field] = value;
    broken[record] = j.dump();
    auto refused = ReadBidsTrials(broken);
    ASSERT_FALSE(refused.ok()) << field;
    EXPECT_EQ(refused.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(refused.status().message().find(record + ": " + field), std::string::npos)
        << refused.status().message();
  }
}

// EDF+ as its specification lays it out: a 256-byte header, 256 bytes per
// signal (EMG and the EDF Annotations signal), then records of 16-bit
// little-endian samples.
struct EdfRead {
  int signals = 0;
  int records = 0;
  std::vector<std::string> labels;
  std::vector<std::string> units;
  std::vector<int> per_record;
  std::vector<std::vector<double>> physical;  // per signal
};

std::string Field(const std::string& edf, std::size_t at, std::size_t size) {
  std::string f = edf.substr(at, size);
  while (!f.empty() && f.back() == ' ') f.pop_back();
  return f;
}

EdfRead ReadEdf(const std::string& edf) {
  EdfRead r;
  r.records = std::stoi(Field(edf, 236, 8));
  r.signals = std::stoi(Field(edf, 252, 4));
  const std::size_t ns = static_cast<std::size_t>(r.signals);
  std::size_t at = 256;
  auto column = [&](std::size_t size) {
    std::vector<std::string> out;
    for (std::size_t i = 0; i < ns; ++i) out.push_back(Field(edf, at + i * size, size));
    at += ns * size;
    return out;
  };
  r.labels = column(16);
  column(80);
  r.units = column(8);
  const auto pmin = column(8), pmax = column(8), dmin = column(8), dmax = column(8);
  column(80);
  for (const std::string& n : column(8)) r.per_record.push_back(std::stoi(n));
  column(32);
  EXPECT_EQ(at, 256 * (ns + 1));
  r.physical.resize(ns);
  for (int rec = 0; rec < r.records; ++rec) {
    for (std::size_t s = 0; s < ns; ++s) {
      const double gain =
          (std::stod(pmax[s]) - std::stod(pmin[s])) / (std::stod(dmax[s]) - std::stod(dmin[s]));
      for (int k = 0; k < r.per_record[s]; ++k, at += 2) {
        const auto lo = static_cast<unsigned char>(edf.at(at));
        const auto hi = static_cast<unsigned char>(edf.at(at + 1));
        const auto digital = static_cast<std::int16_t>(static_cast<std::uint16_t>(lo | (hi << 8)));
        r.physical[s].push_back(std::stod(pmin[s]) + (digital - std::stod(dmin[s])) * gain);
      }
    }
  }
  EXPECT_EQ(at, edf.size());
  return r;
}

TEST(BidsTest, EmgAsEdfHoldsTheSamplesToItsResolution) {
  const Trial trial = BenchLikeTrial();
  FileMap files;
  AddBidsTrial(trial, {"S01", "3", "right", 41}, files);
  const std::string emg =
      "derivatives/fesbench/sub-S01/ses-3/emg/sub-S01_ses-3_task-activeRandomBinaryRb1_run-41";
  const EdfRead edf = ReadEdf(files.at(emg + "_emg.edf"));
  EXPECT_EQ(files.at(emg + "_emg.edf").substr(192, 5), "EDF+C");
  ASSERT_EQ(edf.signals, 2);  // emg_mv and EDF Annotations
  EXPECT_EQ(edf.labels[0], "emg_mv");
  EXPECT_EQ(edf.labels[1], "EDF Annotations");
  EXPECT_EQ(edf.units[0], "mV");
  EXPECT_EQ(edf.per_record[0], 1000);
  EXPECT_EQ(edf.records, 2);  // 2000 samples at 1 kHz
  // Start date and time of the trial (2024-11-23 22:13:20 UTC).
  EXPECT_EQ(Field(files.at(emg + "_emg.edf"), 168, 16), "23.11.2422.13.20");
  const std::vector<double>& exact = *trial.emg->Values("emg_mv");
  ASSERT_EQ(edf.physical[0].size(), exact.size());
  double worst = 0.0;
  for (std::size_t i = 0; i < exact.size(); ++i) {
    worst = std::max(worst, std::abs(edf.physical[0][i] - exact[i]));
  }
  // 16 bits over a range of ±0.01 mV (rounded up to three digits).
  EXPECT_LE(worst, 0.0201 / 65535.0);
  // The sidecars BEP042 asks for; the channels file lists what the EDF holds.
  const auto sidecar = nlohmann::json::parse(files.at(emg + "_emg.json"));
  EXPECT_EQ(sidecar["SamplingFrequency"], 1000.0);
  EXPECT_EQ(sidecar["EMGChannelCount"], 1);
  EXPECT_EQ(files.at(emg + "_channels.tsv"),
            "name\ttype\tunits\tsampling_frequency\tdescription\n"
            "emg_mv\tEMG\tmV\t1000\tsurface EMG, quadriceps\n");
  // No EDF for a rate EDF+ records cannot hold whole.
  ChannelGroup odd = *trial.emg;
  odd.sample_rate_hz = 999.5;
  EXPECT_FALSE(EmgToEdf(odd, std::nullopt));
}

// The exported .mot read by OpenSim's Storage rules: header lines up to
// `endheader` (the first the name, then key=value), inDegrees=yes, nRows
// data rows and nColumns labels, `time` first, the knee as OpenSim's
// coordinate (flexion negative); imported back, the same angles.
TEST(BidsTest, MotionForOpenSimInItsConventions) {
  for (const std::string leg : {"right", "left"}) {
    const Trial trial = BenchLikeTrial();
    FileMap files;
    AddBidsTrial(trial, {"S01", "3", leg, 41}, files);
    const std::string mot = files.at(
        "derivatives/fesbench/sub-S01/ses-3/motion/"
        "sub-S01_ses-3_task-activeRandomBinaryRb1_tracksys-kneebench_run-41_motion.mot");
    std::vector<std::string> lines;
    for (std::size_t start = 0; start < mot.size();) {
      const std::size_t end = mot.find('\n', start);
      ASSERT_NE(end, std::string::npos) << "every line ends";
      lines.push_back(mot.substr(start, end - start));
      start = end + 1;
    }
    const auto endheader = std::find(lines.begin(), lines.end(), "endheader");
    ASSERT_NE(endheader, lines.end());
    EXPECT_EQ(lines.front(), "active_random_binary_rb1");
    std::map<std::string, std::string> header;
    for (auto it = lines.begin() + 1; it != endheader; ++it) {
      const std::size_t eq = it->find('=');
      ASSERT_NE(eq, std::string::npos) << *it;
      header[it->substr(0, eq)] = it->substr(eq + 1);
    }
    EXPECT_EQ(header["version"], "1");
    EXPECT_EQ(header["inDegrees"], "yes");
    const std::string coordinate = leg == "right" ? "knee_angle_r" : "knee_angle_l";
    const std::vector<std::string> labels = {"time", coordinate};
    std::vector<std::string> got;
    std::stringstream row(*(endheader + 1));
    for (std::string label; std::getline(row, label, '\t');) got.push_back(label);
    EXPECT_EQ(got, labels);
    EXPECT_EQ(header["nColumns"], std::to_string(labels.size()));
    const auto rows = static_cast<std::size_t>(lines.end() - endheader - 2);
    EXPECT_EQ(header["nRows"], std::to_string(rows));
    EXPECT_EQ(rows, trial.num_samples());
    // A flexed knee (angle_deg 90) is −90 in OpenSim's gait models.
    std::stringstream first(*(endheader + 2));
    double t = 1.0, knee = 0.0;
    first >> t >> knee;
    EXPECT_EQ(t, 0.0);
    EXPECT_EQ(knee, -(*trial.Values("angle_deg"))[0]);

    auto spec = ImportSpecFromJson({{"kind", "free_swing_passive"},
                                    {"format", "sto"},
                                    {"columns", {{{"column", coordinate}}}}});
    ASSERT_TRUE(spec.ok()) << spec.status().ToString();
    auto back = ImportTrialText(mot, *spec);
    ASSERT_TRUE(back.ok()) << back.status().ToString();
    EXPECT_EQ(*back->Values("angle_deg"), *trial.Values("angle_deg"));
    EXPECT_EQ(*back->Values("t_s"), *trial.Values("t_s"));
  }
}

TEST(BidsTest, LayoutHasTheRequiredFilesAndColumns) {
  FileMap files;
  AddBidsTrial(BenchLikeTrial(), {"S01", "3", "right", 41}, files);
  // Without the dataset files the check names what is missing.
  EXPECT_NE(ValidateBidsLayout(files).message().find("dataset_description.json"),
            std::string::npos);
  files["dataset_description.json"] = R"({"Name": "x", "BIDSVersion": "1.11.0"})";
  files["README.md"] = "x";
  const Status ok = ValidateBidsLayout(files);
  EXPECT_TRUE(ok.ok()) << ok.ToString();
  // A channels file whose columns are out of order, a sidecar without its
  // sampling frequency, a data file with a header row: each named.
  for (const auto& [suffix, bad] : std::vector<std::pair<std::string, std::string>>{
           {"_channels.tsv",
            "name\ttype\tcomponent\ttracked_point\tunits\nt_s\tLATENCY\tn/a\tn/a\ts\n"},
           {"_motion.json", R"({"TaskName": "x", "TrackingSystemName": "y"})"},
           {"_motion.tsv", "t_s\tangle_deg\n0\t1\n"}}) {
    FileMap broken = files;
    const std::string path =
        "sub-S01/ses-3/motion/sub-S01_ses-3_task-activeRandomBinaryRb1_tracksys-kneebench_run-41" +
        suffix;
    broken[path] = bad;
    const Status s = ValidateBidsLayout(broken);
    EXPECT_FALSE(s.ok()) << suffix;
    EXPECT_NE(s.message().find(path), std::string::npos) << s.message();
  }
  // The EMG's sidecar without its reference scheme.
  const std::string emg_json =
      "derivatives/fesbench/sub-S01/ses-3/emg/sub-S01_ses-3_task-activeRandomBinaryRb1_run-41"
      "_emg.json";
  FileMap broken = files;
  auto sidecar = nlohmann::json::parse(files.at(emg_json));
  sidecar.erase("EMGReference");
  broken[emg_json] = sidecar.dump();
  const Status s = ValidateBidsLayout(broken);
  EXPECT_NE(s.message().find(emg_json + ": EMGReference is required"), std::string::npos)
      << s.ToString();
}

TEST(TrialUnitsTest, AccelerometerAndDistanceChannelsHaveUnits) {
  EXPECT_EQ(ChannelUnit("accel_m_s2"), "m/s^2");
  EXPECT_EQ(ChannelUnit("accel_distance_m"), "m");
  EXPECT_EQ(ChannelUnit("accel_deg_s2"), "deg/s^2");
  EXPECT_EQ(ChannelUnit("t_ms"), "ms");
}

TEST(TrialUnitsTest, StorageHeaderCarriesMetadata) {
  ChannelGroup group;
  group.Set("t_s", {0.0, 0.005});
  group.Set("angle_deg", {90.0, 91.0});
  const std::string sto = GroupToSto(group, "swing", {{"fesbench_subject", "S01"}});
  EXPECT_NE(sto.find("inDegrees=yes\nfesbench_subject=S01\nendheader\n"), std::string::npos) << sto;
  ImportSpec spec;
  spec.kind = "free_swing_passive";
  spec.format = "sto";
  auto back = ImportTrialText(sto, spec);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(*back->Values("angle_deg"), (std::vector<double>{90.0, 91.0}));
}

TEST(BidsTest, LabelsAreAlphanumeric) {
  EXPECT_EQ(BidsLabel("FES-01_a"), "FES01a");
  EXPECT_EQ(BidsLabel("__"), "x");
  EXPECT_EQ(BidsTaskLabel("free_swing_passive"), "freeSwingPassive");
}

}  // namespace
}  // namespace fesbench::api
