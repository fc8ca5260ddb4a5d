#include "api/trial.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <functional>

#include <cmath>
#include <filesystem>
#include <limits>
#include <string>

namespace fesbench::api {
namespace {

using ::testing::HasSubstr;

Trial SampleTrial() {
  Trial trial;
  trial.name = "free_swing_passive";
  trial.id = 12;
  trial.start_time_unix_ms = 1714557330123;
  trial.sample_rate_hz = 200.0;
  std::vector<double> t, stim, angle, torque;
  for (int k = 0; k < 5; ++k) {
    t.push_back(k / 200.0);
    stim.push_back(k == 2 ? 35.5 : 0.0);
    angle.push_back(90.0 - 0.1 * k + 1e-13 * k);  // digits that must survive
    torque.push_back(k / -3.0 + 0.0);
  }
  trial.SetChannel("t_s", t);
  trial.SetChannel("stim_ma", stim);
  trial.SetChannel("angle_deg", angle);
  trial.SetChannel("torque_nm", torque);
  ChannelGroup emg;
  emg.sample_rate_hz = 1000.0;
  emg.Set("t_s", {0.0, 0.001, 0.002});
  emg.Set("emg_mv", {0.01, -0.02, 0.005});
  trial.emg = emg;
  return trial;
}

// The CSV error message for `text`, which must fail.
std::string CsvError(std::string_view text) {
  Result<Trial> r = TrialFromCsv(text);
  EXPECT_FALSE(r.ok()) << "accepted:\n" << text;
  if (r.ok()) return "";
  EXPECT_EQ(r.status().code(), ErrorCode::kInvalidArgument);
  return r.status().message();
}

TEST(ChannelUnit, FollowsNameSuffix) {
  EXPECT_EQ(ChannelUnit("t_s"), "s");
  EXPECT_EQ(ChannelUnit("stim_ma"), "mA");
  EXPECT_EQ(ChannelUnit("angle_deg"), "deg");
  EXPECT_EQ(ChannelUnit("velocity_deg_s"), "deg/s");
  EXPECT_EQ(ChannelUnit("accel_deg_s2"), "deg/s^2");
  EXPECT_EQ(ChannelUnit("torque_nm"), "N.m");
  EXPECT_EQ(ChannelUnit("emg_mv"), "mV");
  EXPECT_EQ(ChannelUnit("activation"), "1");
  EXPECT_EQ(ChannelUnit("motor_setpoint_deg"), "deg");
  EXPECT_EQ(ChannelUnit("counter"), "");
}

TEST(Trial, FindsAndReplacesChannelsByName) {
  Trial trial = SampleTrial();
  ASSERT_NE(trial.FindChannel("angle_deg"), nullptr);
  EXPECT_EQ(trial.FindChannel("angle_deg")->unit, "deg");
  EXPECT_EQ(trial.FindChannel("velocity_deg_s"), nullptr);
  EXPECT_EQ(trial.Values("missing"), nullptr);
  EXPECT_EQ(trial.num_samples(), 5u);
  trial.SetChannel("stim_ma", {1, 2, 3, 4, 5});
  EXPECT_EQ(trial.channels.size(), 4u);
  EXPECT_EQ((*trial.Values("stim_ma"))[4], 5.0);
  ASSERT_TRUE(trial.emg.has_value());
  EXPECT_EQ(trial.emg->Find("emg_mv")->unit, "mV");
  EXPECT_EQ(trial.emg->num_samples(), 3u);
  EXPECT_TRUE(ValidateTrial(trial).ok());
}

TEST(Trial, ValidateRejectsBrokenTrials) {
  Trial trial = SampleTrial();
  trial.SetChannel("stim_ma", {1, 2});
  Status s = ValidateTrial(trial);
  EXPECT_EQ(s.field(), "channels[1].values");

  trial = SampleTrial();
  trial.channels.erase(trial.channels.begin());
  EXPECT_EQ(ValidateTrial(trial).field(), "channels");

  trial = SampleTrial();
  trial.emg->channels[0].values = {0.0, 0.0, 0.002};
  EXPECT_EQ(ValidateTrial(trial).field(), "emg.channels[0].values[1]");

  trial = SampleTrial();
  trial.channels[2].values[3] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(ValidateTrial(trial).field(), "channels[2].values[3]");

  trial = SampleTrial();
  trial.sample_rate_hz = 0.0;
  EXPECT_EQ(ValidateTrial(trial).field(), "sample_rate_hz");

  trial = SampleTrial();
  trial.channels[3].name = "Torque";
  EXPECT_EQ(ValidateTrial(trial).field(), "channels[3].name");
}

TEST(TrialCsv, WritesHeaderAndRoundTripsExactly) {
  const Trial trial = SampleTrial();
  const std::string csv = TrialToCsv(trial);
  EXPECT_TRUE(csv.starts_with("t_s,stim_ma,angle_deg,torque_nm\n0,0,90,0\n")) << csv;
  Result<Trial> back = TrialFromCsv(csv);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->channels, trial.channels);  // bit-exact values, units from names
  EXPECT_NEAR(back->sample_rate_hz, 200.0, 1e-9);
  EXPECT_FALSE(back->id.has_value());
}

TEST(TrialCsv, AcceptsCrlfBomSpacesAndTrailingBlankLines) {
  Result<Trial> r = TrialFromCsv("\xEF\xBB\xBFt_s, stim_ma\r\n0, 1.5\r\n0.005 ,+2e1\r\n\r\n\n");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(*r->Values("stim_ma"), (std::vector<double>{1.5, 20.0}));
  EXPECT_NEAR(r->sample_rate_hz, 200.0, 1e-9);
}

TEST(TrialCsv, SingleRowUsesDefaultRate) {
  Result<Trial> r = TrialFromCsv("t_s,stim_ma\n0.5,3\n", 1000.0);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->sample_rate_hz, 1000.0);
}

TEST(TrialCsv, RejectsEmptyFile) {
  EXPECT_THAT(CsvError(""), HasSubstr("empty file"));
  EXPECT_THAT(CsvError("\n\r\n  \n"), HasSubstr("empty file"));
}

TEST(TrialCsv, RejectsMissingHeader) {
  EXPECT_THAT(CsvError("0,1\n0.005,2\n"), HasSubstr("line 1: missing header"));
}

TEST(TrialCsv, RejectsHeaderOnly) {
  EXPECT_THAT(CsvError("t_s,stim_ma\n"), HasSubstr("no data rows"));
}

TEST(TrialCsv, RejectsEmptyInvalidOrDuplicateNames) {
  EXPECT_THAT(CsvError("t_s,,angle_deg\n0,1,2\n"), HasSubstr("line 1, column 2: empty channel"));
  EXPECT_THAT(CsvError("t_s,Angle (deg)\n0,1\n"),
              HasSubstr("line 1, column 2: invalid channel name 'Angle (deg)'"));
  EXPECT_THAT(CsvError("t_s,angle_deg,angle_deg\n0,1,2\n"),
              HasSubstr("line 1, column 3: duplicate channel name 'angle_deg'"));
}

TEST(TrialCsv, RejectsMissingTimeColumn) {
  EXPECT_THAT(CsvError("stim_ma,angle_deg\n0,1\n"), HasSubstr("no t_s column"));
}

TEST(TrialCsv, RejectsWrongColumnCountNamingTheLine) {
  EXPECT_THAT(CsvError("t_s,stim_ma,angle_deg\n0,1,2\n0.005,1\n"),
              HasSubstr("line 3: expected 3 columns, found 2"));
  EXPECT_THAT(CsvError("t_s,stim_ma\n0,1\n0.005,1\n0.01,1,7\n"),
              HasSubstr("line 4: expected 2 columns, found 3"));
}

TEST(TrialCsv, RejectsBlankLineBetweenRows) {
  EXPECT_THAT(CsvError("t_s,stim_ma\n0,1\n\n0.01,1\n"), HasSubstr("line 3: blank line"));
}

TEST(TrialCsv, RejectsNonNumericValuesNamingLineAndColumn) {
  EXPECT_THAT(CsvError("t_s,stim_ma,angle_deg\n0,1,2\n0.005,1,abc\n"),
              HasSubstr("line 3, column 3 (angle_deg): 'abc' is not a number"));
  EXPECT_THAT(CsvError("t_s,stim_ma\n0,\n"),
              HasSubstr("line 2, column 2 (stim_ma): '' is not a number"));
  EXPECT_THAT(CsvError("t_s,stim_ma\n0,1.5x\n"), HasSubstr("'1.5x' is not a number"));
  EXPECT_THAT(CsvError("t_s,stim_ma\n0,\"1\"\n"), HasSubstr("is not a number"));
  Result<Trial> r = TrialFromCsv("t_s,stim_ma\n0,x\n");
  EXPECT_EQ(r.status().field(), "stim_ma");
}

TEST(TrialCsv, RejectsNanAndInfinity) {
  EXPECT_THAT(CsvError("t_s,stim_ma\n0,nan\n"),
              HasSubstr("line 2, column 2 (stim_ma): 'nan' is not finite"));
  EXPECT_THAT(CsvError("t_s,stim_ma\n0,1\n0.005,-inf\n"),
              HasSubstr("line 3, column 2 (stim_ma): '-inf' is not finite"));
  EXPECT_THAT(CsvError("t_s,stim_ma\n0,1e400\n"), HasSubstr("line 2, column 2"));
}

TEST(TrialCsv, RejectsNonIncreasingTime) {
  EXPECT_THAT(
      CsvError("stim_ma,t_s\n1,0\n1,0.005\n1,0.005\n"),
      HasSubstr("line 4, column 2 (t_s): time 0.005 is not greater than the previous 0.005"));
  EXPECT_THAT(CsvError("t_s,stim_ma\n0.01,1\n0.005,1\n"), HasSubstr("line 3, column 1 (t_s)"));
}

TEST(TrialSto, WritesOpenSimStorageHeaderAndTabSeparatedRows) {
  const std::string sto = TrialToSto(SampleTrial());
  EXPECT_TRUE(
      sto.starts_with("free_swing_passive\nversion=1\nnRows=5\nnColumns=4\n"
                      "inDegrees=yes\nendheader\n"
                      "time\tstim_ma\tangle_deg\ttorque_nm\n"
                      "0\t0\t90\t0\n0.005\t0\t"))
      << sto;
  // One header block of 7 lines plus 5 rows.
  EXPECT_EQ(std::count(sto.begin(), sto.end(), '\n'), 12);
}

TEST(TrialSto, PutsTimeFirstWhateverItsColumn) {
  ChannelGroup group;
  group.Set("angle_deg", {10, 11});
  group.Set("t_s", {0, 0.005});
  EXPECT_EQ(GroupToSto(group, "x"),
            "x\nversion=1\nnRows=2\nnColumns=2\ninDegrees=yes\nendheader\n"
            "time\tangle_deg\n0\t10\n0.005\t11\n");
}

TEST(TrialJson, RoundTripsLosslesslyIncludingEmg) {
  const Trial trial = SampleTrial();
  const nlohmann::json json = TrialToJson(trial);
  EXPECT_EQ(json["channels"][2]["unit"], "deg");
  EXPECT_EQ(json["emg"]["sample_rate_hz"], 1000.0);
  Result<Trial> back = TrialFromJson(nlohmann::json::parse(json.dump()));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(*back, trial);
}

TEST(TrialJson, RoundTripsTheDeliveredPulses) {
  Trial trial = SampleTrial();
  PulseRecord pulses;
  pulses.pulse_rate_hz = 33.0;
  pulses.pulse_width_us = 300.0;
  pulses.Append(0.0, 20.0);
  pulses.Append(1.0 / 33.0, 20.5);
  pulses.Append(0.25, 40.0);
  trial.pulses = pulses;
  const nlohmann::json json = TrialToJson(trial);
  EXPECT_EQ(json["pulses"]["pulse_rate_hz"], 33.0);
  EXPECT_EQ(json["pulses"]["stim_ma"].size(), 3u);
  Result<Trial> back = TrialFromJson(nlohmann::json::parse(json.dump()));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(*back, trial);
  EXPECT_EQ(back->pulses->Train()[2], (model::Pulse{0.25, 40.0}));
}

// A hardware stimulator's command log: bit-exact both ways, refused
// naming the field when it does not hold.
TEST(TrialJson, RoundTripsTheDeviceCommandsAndRefusesBadOnes) {
  Trial trial = SampleTrial();
  const DeviceCommandLog log{.device = "sciencemode2",
                             .pulse_rate_hz = 1000.0 / 30.5,
                             .current_step_ma = 1.0,
                             .start_monotonic_ns = 123456789012345,
                             .t_s = {0.0001234, 0.0305, 0.061},
                             .requested_ma = {12.75, 13.2, 40.0},
                             .commanded_ma = {12.0, 13.0, 40.0},
                             .single_pulse = {false, false, true}};
  trial.device_commands = log;
  const nlohmann::json json = TrialToJson(trial);
  EXPECT_EQ(json["device_commands"]["single_pulse"], nlohmann::json::parse("[false,false,true]"));
  Result<Trial> back = TrialFromJson(nlohmann::json::parse(json.dump()));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(*back, trial);
  const auto field_of = [&](const std::function<void(nlohmann::json&)>& edit) {
    nlohmann::json bad = json;
    edit(bad["device_commands"]);
    Result<Trial> r = TrialFromJson(bad);
    return r.ok() ? std::string("<accepted>") : r.status().field();
  };
  EXPECT_EQ(field_of([](auto& d) { d["device"] = ""; }), "device_commands.device");
  EXPECT_EQ(field_of([](auto& d) { d["pulse_rate_hz"] = 0; }), "device_commands.pulse_rate_hz");
  EXPECT_EQ(field_of([](auto& d) { d.erase("start_monotonic_ns"); }),
            "device_commands.start_monotonic_ns");
  EXPECT_EQ(field_of([](auto& d) { d["t_s"][2] = 0.01; }), "device_commands.t_s[2]");
  EXPECT_EQ(field_of([](auto& d) { d["commanded_ma"][1] = 14.0; }),
            "device_commands.commanded_ma[1]");  // above what was asked
  EXPECT_EQ(field_of([](auto& d) { d["requested_ma"].erase(1); }), "device_commands.requested_ma");
  EXPECT_EQ(field_of([](auto& d) { d["single_pulse"][0] = 1; }),
            "device_commands.single_pulse[0]");
}

TEST(TrialJson, RejectsBadPulsesWithTheirPath) {
  auto field_of = [](std::string_view pulses) {
    const std::string text = R"({"sample_rate_hz": 200, "channels": [{"name": "t_s",
        "values": [0]}], "pulses": )" + std::string(pulses) + "}";
    Result<Trial> r = TrialFromJson(nlohmann::json::parse(text));
    EXPECT_FALSE(r.ok()) << text;
    return r.ok() ? std::string("<accepted>") : r.status().field();
  };
  EXPECT_EQ(field_of("[]"), "pulses");
  EXPECT_EQ(field_of(R"({"pulse_width_us": 300, "t_s": [], "stim_ma": []})"),
            "pulses.pulse_rate_hz");
  EXPECT_EQ(field_of(R"({"pulse_rate_hz": 0, "pulse_width_us": 300, "t_s": [], "stim_ma": []})"),
            "pulses.pulse_rate_hz");
  EXPECT_EQ(field_of(R"({"pulse_rate_hz": 33, "pulse_width_us": 300, "t_s": [0, "a"],
      "stim_ma": [1, 2]})"),
            "pulses.t_s[1]");
  EXPECT_EQ(field_of(R"({"pulse_rate_hz": 33, "pulse_width_us": 300, "t_s": [0, -1],
      "stim_ma": [1, 2]})"),
            "pulses.t_s[1]");
  EXPECT_EQ(field_of(R"({"pulse_rate_hz": 33, "pulse_width_us": 300, "t_s": [0, 1],
      "stim_ma": [1, -2]})"),
            "pulses.stim_ma[1]");
  EXPECT_EQ(field_of(R"({"pulse_rate_hz": 33, "pulse_width_us": 300, "t_s": [0, 1],
      "stim_ma": [1]})"),
            "pulses.stim_ma");
}

TEST(TrialJson, OmitsAbsentOptionalsAndDefaultsUnits) {
  Trial trial;
  trial.SetChannel("t_s", {0.0});
  const nlohmann::json json = TrialToJson(trial);
  EXPECT_FALSE(json.contains("id"));
  EXPECT_FALSE(json.contains("emg"));
  Result<Trial> r = TrialFromJson(nlohmann::json::parse(
      R"({"sample_rate_hz": 200, "channels": [{"name": "t_s", "values": [0, 0.005]},
          {"name": "torque_nm", "values": [1, 2]}]})"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->FindChannel("torque_nm")->unit, "N.m");
}

TEST(TrialJson, RejectsBadFieldsWithTheirPath) {
  auto field_of = [](std::string_view text) {
    Result<Trial> r = TrialFromJson(nlohmann::json::parse(text));
    EXPECT_FALSE(r.ok()) << text;
    return r.ok() ? std::string("<accepted>") : r.status().field();
  };
  EXPECT_EQ(field_of(R"({"channels": []})"), "sample_rate_hz");
  EXPECT_EQ(field_of(R"({"sample_rate_hz": "200", "channels": []})"), "sample_rate_hz");
  EXPECT_EQ(field_of(R"({"sample_rate_hz": 200})"), "channels");
  EXPECT_EQ(field_of(R"({"sample_rate_hz": 200, "channels": []})"), "channels");  // no t_s
  EXPECT_EQ(field_of(R"({"id": 1.5, "sample_rate_hz": 200, "channels": []})"), "id");
  EXPECT_EQ(field_of(R"({"sample_rate_hz": 200, "channels": [{"name": "t_s",
      "values": [0, "x"]}]})"),
            "channels[0].values[1]");
  EXPECT_EQ(field_of(R"({"sample_rate_hz": 200, "channels": [{"values": [0]}]})"),
            "channels[0].name");
  EXPECT_EQ(field_of(R"({"sample_rate_hz": 200, "channels": [{"name": "t_s", "values": [0]}],
      "emg": {"sample_rate_hz": -1, "channels": []}})"),
            "emg.sample_rate_hz");
}

TEST(TrialFiles, ReadsCsvFromDiskAndReportsMissingFiles) {
  const std::filesystem::path dir = testing::TempDir();
  const std::filesystem::path path = dir / "fesbench_trial_test.csv";
  ASSERT_TRUE(WriteTextFile(path, TrialToCsv(SampleTrial())).ok());
  Result<Trial> r = ReadTrialCsvFile(path);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->num_samples(), 5u);
  ASSERT_TRUE(WriteTextFile(path, "t_s,stim_ma\n0,oops\n").ok());
  r = ReadTrialCsvFile(path);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.status().message(), HasSubstr(path.string() + ": line 2, column 2"));
  std::filesystem::remove(path);
  r = ReadTrialCsvFile(path);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), ErrorCode::kNotFound);
}

}  // namespace
}  // namespace fesbench::api
