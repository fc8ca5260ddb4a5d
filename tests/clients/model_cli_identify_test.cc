// In-process tests of `fesbench-model identify` (clients/model_cli): trials
// simulated by the model library, written as CSV, identified through the
// command line, and the parameter set read back.

#include <gtest/gtest.h>

#include <algorithm>
#include <unistd.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "api/parameter_set_json.h"
#include "api/trial.h"
#include "clients/model_cli/cli.h"
#include "model/contraction.h"
#include "model/parameter_set.h"
#include "model/simulate.h"
#include "model/stimulus_generators.h"

namespace fesbench::cli {
namespace {

namespace fs = std::filesystem;

class IdentifyCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) / ("fesbench_identify_cli_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  std::string WriteTrial(const std::string& name, const model::SimulationResult& r) {
    api::Trial t;
    t.sample_rate_hz = 200.0;
    t.SetChannel("t_s", r.t_s);
    t.SetChannel("stim_ma", r.stim_ma);
    t.SetChannel("angle_deg", r.angle_deg);
    t.SetChannel("velocity_deg_s", r.velocity_deg_s);
    t.SetChannel("accel_deg_s2", r.accel_deg_s2);
    t.SetChannel("torque_nm", r.torque_nm);
    t.SetChannel("activation", r.activation);
    EXPECT_TRUE(api::WriteTextFile(dir_ / name, api::TrialToCsv(t)).ok());
    return Path(name);
  }

  // A recording as a bench without accelerometer makes it: the stimulation
  // envelope and the knee angle only.
  void WriteRecording(const std::string& name, const model::SampledSignal& env,
                      const model::SimulationResult& sim) {
    api::Trial t;
    t.sample_rate_hz = 200.0;
    t.SetChannel("t_s", sim.t_s);
    t.SetChannel("stim_ma", std::vector<double>(env.values.begin(),
                                                env.values.begin() +
                                                    static_cast<std::ptrdiff_t>(sim.size())));
    t.SetChannel("angle_deg", sim.angle_deg);
    ASSERT_TRUE(api::WriteTextFile(dir_ / name, api::TrialToCsv(t)).ok());
  }

  int Run(std::vector<std::string> args) {
    args.insert(args.begin(), "fesbench-model");
    std::vector<const char*> argv;
    for (const auto& a : args) argv.push_back(a.c_str());
    out_.str("");
    err_.str("");
    return RunModelCli(static_cast<int>(argv.size()), argv.data(), out_, err_);
  }

  model::ParameterSet ReadParams(const std::string& path) {
    const auto text = api::ReadTextFile(path);
    EXPECT_TRUE(text.ok());
    auto p = api::ParameterSetFromJson(nlohmann::json::parse(*text));
    EXPECT_TRUE(p.ok());
    return *p;
  }

  fs::path dir_;
  std::ostringstream out_, err_;
};

TEST_F(IdentifyCliTest, IsometricRampGivesPoleAndIrc) {
  const model::ParameterSet truth = model::ExampleParameterSet();
  const auto env =
      model::MakeStimulus("isometric_ramp_irc", {{"threshold_ma", 20}, {"max_ma", 45}});
  model::SimulationOptions opt;
  opt.duration_s = env.EndTime();
  const std::string trial = WriteTrial(
      "ramp.csv", model::SimulateIsometric(truth, model::PulsesFromEnvelope(env, 33.0), 90.0, opt));
  ASSERT_EQ(Run({"identify", "contraction", "--trial", trial, "--out", Path("c.json")}), kExitOk)
      << err_.str();
  EXPECT_NEAR(ReadParams(Path("c.json")).contraction.pole_per_s, 25.0, 0.5);
  const std::string summary = out_.str();
  EXPECT_EQ(std::count(summary.begin(), summary.end(), '\n'), 1);  // a one-line summary
  const auto report = nlohmann::json::parse(summary);
  EXPECT_TRUE(report["fit_rms"].contains("twitch_order3_ls"));

  ASSERT_EQ(Run({"identify", "irc_ramp_correlation", "--trial", trial, "--params-in",
                 Path("c.json"), "--option", "ramp_points=31", "--out", Path("i.json")}),
            kExitOk)
      << err_.str();
  const model::ParameterSet p = ReadParams(Path("i.json"));
  EXPECT_EQ(p.irc.size(), 32u);  // 31 grid points and (0 mA, 0)
  EXPECT_NEAR(p.irc(40.0), truth.irc(40.0), 0.03);
  EXPECT_EQ(p.provenance.irc_method, "ramp_correlation");
  EXPECT_NEAR(p.contraction.pole_per_s, 25.0, 0.5);  // kept from --params-in
}

TEST_F(IdentifyCliTest, FreeSwingActiveWithPassiveFromParamsIn) {
  const model::ParameterSet truth = model::ExampleParameterSet();
  const auto env = model::MakeStimulus("random_binary_dense", {{"amplitude_ma", 40}, {"seed", 2}});
  model::SimulationOptions opt;
  opt.duration_s = env.EndTime();
  const std::string trial = WriteTrial(
      "rb.csv", model::SimulateFreeSwing(truth, model::PulsesFromEnvelope(env, 33.0), opt));
  const std::string params = (dir_ / "truth.json").string();
  ASSERT_TRUE(api::WriteTextFile(params, api::ParameterSetToJson(truth).dump()).ok());
  ASSERT_EQ(
      Run({"identify", "active", "--trial", trial, "--params-in", params, "--out", Path("a.json")}),
      kExitOk)
      << err_.str();
  const model::ParameterSet p = ReadParams(Path("a.json"));
  // 41.7 N·m since the pulse-timing rule (the trial's stim_ma column is the
  // simulator's stimulus column, re-read into pulses); 39–41 before.
  EXPECT_NEAR(p.active.torque_scale_nm, 40.0, 2.0);
  EXPECT_EQ(p.provenance.active_method, "log_least_squares");
  ASSERT_EQ(Run({"identify", "single_segment", "--trial", trial, "--params-in", params, "--out",
                 Path("s.json")}),
            kExitOk)
      << err_.str();
  EXPECT_EQ(ReadParams(Path("s.json")).model, model::ModelKind::kSingleSegment);
}

TEST_F(IdentifyCliTest, FreeSwingFromPositionAndEnvelopeOnly) {
  // A recording without accelerometer or activation: kinematics by GCV
  // spline (§5.1, §7.4.1), f_stim from the envelope and --params-in.
  const model::ParameterSet truth = model::ExampleParameterSet();
  const auto env = model::MakeStimulus("random_binary_sparse", {{"amplitude_ma", 26}, {"seed", 4}});
  model::SimulationOptions opt;
  opt.duration_s = env.EndTime();
  WriteRecording("fs.csv", env,
                 model::SimulateFreeSwing(truth, model::PulsesFromEnvelope(env, 33.0), opt));
  const std::string params = Path("truth.json");
  ASSERT_TRUE(api::WriteTextFile(params, api::ParameterSetToJson(truth).dump()).ok());
  ASSERT_EQ(Run({"identify", "passive_free_swing", "--trial", Path("fs.csv"), "--params-in", params,
                 "--option", "derive_kinematics=gcv", "--out", Path("p.json")}),
            kExitOk)
      << err_.str();
  const model::ParameterSet p = ReadParams(Path("p.json"));
  EXPECT_NEAR(p.passive.inertia_kgm2, truth.passive.inertia_kgm2,
              0.05 * truth.passive.inertia_kgm2);
  EXPECT_EQ(p.provenance.passive_method, "free_swing");
}

TEST_F(IdentifyCliTest, OutputErrorRecoversTheTorqueScaleAndEvaluatesAtZeroIterations) {
  // A free swing of the example knee between the bench's stops, recorded as
  // position and envelope only; the start set's τ_scale is 20 % low.
  const model::ParameterSet truth = model::ExampleParameterSet();
  const auto env = model::MakeStimulus("random_binary_dense", {{"amplitude_ma", 40}, {"seed", 2}});
  model::SimulationOptions opt;
  opt.duration_s = env.EndTime();
  opt.joint_limits = model::JointLimits{10.0, 110.0};
  WriteRecording("rb.csv", env,
                 model::SimulateFreeSwing(truth, model::PulsesFromEnvelope(env, 33.0), opt));
  model::ParameterSet start = truth;
  start.active.torque_scale_nm *= 0.8;
  ASSERT_TRUE(api::WriteTextFile(Path("truth.json"), api::ParameterSetToJson(truth).dump()).ok());
  ASSERT_TRUE(api::WriteTextFile(Path("start.json"), api::ParameterSetToJson(start).dump()).ok());
  const auto error_deg = [&](const std::string& params, int iterations) {
    EXPECT_EQ(Run({"identify", "output_error", "--trial", Path("rb.csv"), "--params-in", params,
                   "--option", "iterations=" + std::to_string(iterations), "--option",
                   "min_angle_deg=10", "--option", "max_angle_deg=110", "--out", Path("r.json")}),
              kExitOk)
        << err_.str();
    return nlohmann::json::parse(out_.str())["fit_rms"]["output_error_deg"].get<double>();
  };
  // The truth reproduces its own swing (initial velocity from the spline).
  EXPECT_LT(error_deg(Path("truth.json"), 0), 0.2);
  const double start_error = error_deg(Path("start.json"), 0);
  EXPECT_GT(start_error, 2.0);
  EXPECT_LT(error_deg(Path("start.json"), 10), 0.2 * start_error);
  EXPECT_NEAR(ReadParams(Path("r.json")).active.torque_scale_nm, truth.active.torque_scale_nm,
              0.05 * truth.active.torque_scale_nm);

  EXPECT_EQ(Run({"identify", "output_error", "--trial", Path("rb.csv"), "--params-in",
                 Path("start.json"), "--option", "min_angle_deg=10", "--out", Path("r.json")}),
            kExitUsage);
  EXPECT_NE(err_.str().find("both stops"), std::string::npos);
  EXPECT_EQ(Run({"identify", "output_error", "--trial", Path("rb.csv"), "--params-in",
                 Path("start.json"), "--option", "iterations=-1", "--out", Path("r.json")}),
            kExitUsage);
}

TEST_F(IdentifyCliTest, UsageErrors) {
  EXPECT_EQ(Run({"identify", "no_such_method", "--trial", "x.csv", "--out", Path("o.json")}),
            kExitUsage);
  const model::ParameterSet truth = model::ExampleParameterSet();
  const auto env = model::MakeStimulus("impulses", {{"max_ma", 45}});
  model::SimulationOptions opt;
  opt.duration_s = env.EndTime();
  const std::string trial = WriteTrial(
      "imp.csv", model::SimulateIsometric(truth, model::PulsesFromEnvelope(env, 33.0), 90.0, opt));
  EXPECT_EQ(Run({"identify", "contraction", "--trial", trial, "--option", "bogus=1", "--out",
                 Path("o.json")}),
            kExitUsage);
  EXPECT_NE(err_.str().find("bogus"), std::string::npos);
  // Data the method cannot use: bad input, one line.
  EXPECT_EQ(Run({"identify", "irc_step", "--trial", trial, "--out", Path("o.json")}),
            kExitBadInput);
  EXPECT_NE(err_.str().find("burst"), std::string::npos);
}

}  // namespace
}  // namespace fesbench::cli
