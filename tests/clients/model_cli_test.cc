// Integration tests of the fesbench-model binary: runs it on temporary files
// and checks outputs, exit codes and one-line error messages.

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "api/parameter_set_json.h"
#include "api/trial.h"
#include "model/parameter_set.h"

#ifndef FESBENCH_MODEL_EXE
#error "FESBENCH_MODEL_EXE must name the fesbench-model binary"
#endif

namespace fesbench::cli {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::StartsWith;

struct RunResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

class ModelCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    static std::atomic<int> counter{0};
    dir_ = fs::path(::testing::TempDir()) /
           ("fesbench_model_cli_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::create_directories(dir_);
    params_ = Write("params.json", api::ParameterSetToJson(model::ExampleParameterSet()).dump(2));
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  std::string Write(const std::string& name, const std::string& text) {
    EXPECT_TRUE(api::WriteTextFile(dir_ / name, text).ok());
    return Path(name);
  }

  static std::string Read(const std::string& path) {
    api::Result<std::string> text = api::ReadTextFile(path);
    return text.ok() ? *text : std::string();
  }

  // Runs the binary with `args` (already shell-quoted where needed).
  RunResult Run(const std::string& args) const {
    const std::string out = (dir_ / "stdout.txt").string();
    const std::string err = (dir_ / "stderr.txt").string();
    const std::string command =
        std::string("'") + FESBENCH_MODEL_EXE + "' " + args + " >'" + out + "' 2>'" + err + "'";
    const int status = std::system(command.c_str());
    RunResult r;
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    r.out = Read(out);
    r.err = Read(err);
    return r;
  }

  // Expects a failure with `exit_code` and exactly one error line on
  // stderr containing `needle`.
  void ExpectError(const std::string& args, int exit_code, const std::string& needle) const {
    SCOPED_TRACE(args);
    const RunResult r = Run(args);
    EXPECT_EQ(r.exit_code, exit_code) << r.err;
    EXPECT_THAT(r.err, StartsWith("fesbench-model: error: "));
    EXPECT_THAT(r.err, HasSubstr(needle));
    ASSERT_FALSE(r.err.empty());
    EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << "not one line: " << r.err;
    EXPECT_EQ(r.out, "");
  }

  api::Trial ReadCsv(const std::string& path) const {
    api::Result<api::Trial> t = api::ReadTrialCsvFile(path);
    EXPECT_TRUE(t.ok()) << t.status().ToString();
    return t.ok() ? *t : api::Trial{};
  }

  fs::path dir_;
  std::string params_;
};

std::vector<std::string> ChannelNames(const api::Trial& t) {
  std::vector<std::string> names;
  for (const api::Channel& c : t.channels) names.push_back(c.name);
  return names;
}

const std::vector<std::string> kSimulationColumns = {
    "t_s", "stim_ma", "angle_deg", "velocity_deg_s", "accel_deg_s2", "torque_nm", "activation"};

TEST_F(ModelCliTest, StimulusThenFreeSwingSimulationRoundTrip) {
  const std::string stim = Path("step.csv");
  RunResult r = Run("stimulus prediction_step --param max_ma=40 --out '" + stim + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  const api::Trial s = ReadCsv(stim);
  EXPECT_EQ(ChannelNames(s), (std::vector<std::string>{"t_s", "stim_ma"}));
  ASSERT_EQ(s.num_samples(), 1000u);  // 5 s at 200 Hz (§5.4.5)
  // threshold 20 + 0.75 * (40 - 20) = 35 mA from 0.5 s for 3 s.
  EXPECT_EQ((*s.Values("stim_ma"))[99], 0.0);
  EXPECT_DOUBLE_EQ((*s.Values("stim_ma"))[100], 35.0);
  EXPECT_DOUBLE_EQ((*s.Values("stim_ma"))[699], 35.0);
  EXPECT_EQ((*s.Values("stim_ma"))[700], 0.0);

  const std::string out = Path("swing.csv");
  r = Run("simulate --params '" + params_ + "' --stimulus '" + stim +
          "' --mode free_swing --out '" + out + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  const api::Trial sim = ReadCsv(out);
  EXPECT_EQ(ChannelNames(sim), kSimulationColumns);
  ASSERT_EQ(sim.num_samples(), 1000u);
  EXPECT_NEAR(sim.sample_rate_hz, 200.0, 1e-9);
  EXPECT_DOUBLE_EQ((*sim.Values("t_s"))[999], 999 / 200.0);
  // Stimulation extends the knee: the angle ends well below its start.
  const std::vector<double>& angle = *sim.Values("angle_deg");
  EXPECT_EQ(angle[0], 90.0);
  double min_angle = angle[0];
  for (double a : angle) min_angle = std::min(min_angle, a);
  EXPECT_LT(min_angle, 60.0);
  EXPECT_GT((*sim.Values("activation"))[600], 0.5);
  EXPECT_EQ((*sim.Values("activation"))[50], 0.0);
}

TEST_F(ModelCliTest, FreeSwingStopsAtTheGivenRangeOfMotion) {
  const std::string stim = Path("rb.csv");
  ASSERT_EQ(
      Run("stimulus random_binary_dense --param amplitude_ma=45 --out '" + stim + "'").exit_code,
      0);
  const auto extremes = [&](const std::string& stops) {
    const std::string out = Path("swing.csv");
    const RunResult r = Run("simulate --params '" + params_ + "' --stimulus '" + stim +
                            "' --angle-deg 60 " + stops + " --out '" + out + "'");
    EXPECT_EQ(r.exit_code, 0) << r.err;
    const api::Trial swing = ReadCsv(out);
    const std::vector<double>& angle = *swing.Values("angle_deg");
    return std::pair(*std::min_element(angle.begin(), angle.end()),
                     *std::max_element(angle.begin(), angle.end()));
  };
  // Without stops the strong train extends the knee past the bench's 10°.
  EXPECT_LT(extremes("").first, 10.0);
  const auto [lo, hi] = extremes("--stops 10 110");
  EXPECT_GE(lo, 10.0);
  EXPECT_LE(hi, 110.0);
  EXPECT_NEAR(lo, 10.0, 1e-6);  // it reaches full extension and stays there
}

TEST_F(ModelCliTest, IsometricTorqueRisesWithStimulationAndWritesSto) {
  const std::string stim = Path("step.csv");
  ASSERT_EQ(Run("stimulus prediction_step --out '" + stim + "'").exit_code, 0);
  const std::string out = Path("iso.sto");
  RunResult r = Run("simulate --params '" + params_ + "' --stimulus '" + stim +
                    "' --mode isometric --angle-deg 60 --integrator adaptive --out '" + out + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string sto = Read(out);
  EXPECT_THAT(sto, StartsWith("simulated_isometric\nversion=1\nnRows=1000\nnColumns=7\n"
                              "inDegrees=yes\nendheader\ntime\tstim_ma\tangle_deg\t"));
  // Same run as CSV to read the numbers back.
  const std::string csv = Path("iso.csv");
  ASSERT_EQ(Run("simulate --params '" + params_ + "' --stimulus '" + stim +
                "' --mode isometric --angle-deg 60 --out '" + csv + "'")
                .exit_code,
            0);
  const api::Trial sim = ReadCsv(csv);
  const std::vector<double>& torque = *sim.Values("torque_nm");
  const std::vector<double>& angle = *sim.Values("angle_deg");
  for (double a : angle) ASSERT_EQ(a, 60.0);
  EXPECT_GT(torque[650] - torque[90], 10.0);  // Eq. 3.18: rises positive
}

TEST_F(ModelCliTest, TrajectoryModeFollowsTheTrajectoryFile) {
  std::string traj = "t_s,angle_deg,velocity_deg_s,accel_deg_s2\n";
  for (int i = 0; i < 400; ++i) traj += std::to_string(i / 200.0) + ",45,0,0\n";
  const std::string traj_path = Write("traj.csv", traj);
  const std::string stim = Write("zero.csv", "t_s,stim_ma\n0,0\n0.005,0\n");
  const std::string out = Path("traj_out.json");
  RunResult r = Run("simulate --params '" + params_ + "' --stimulus '" + stim +
                    "' --mode trajectory --trajectory '" + traj_path + "' --out '" + out + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  api::Result<api::Trial> sim = api::TrialFromJson(nlohmann::json::parse(Read(out)));
  ASSERT_TRUE(sim.ok()) << sim.status().ToString();
  ASSERT_EQ(sim->num_samples(), 400u);
  EXPECT_EQ((*sim->Values("angle_deg"))[399], 45.0);
  // At rest with no stimulation the brace holds the passive torque τ_pta(45°) + τ_ptv(0).
  const model::ParameterSet p = model::ExampleParameterSet();
  EXPECT_NEAR((*sim->Values("torque_nm"))[200],
              p.passive.torque_angle(45.0) + p.passive.torque_velocity(0.0), 1e-9);
}

TEST_F(ModelCliTest, TrajectoryGeneratorThenTrajectorySimulation) {
  const std::string traj = Path("sines.csv");
  RunResult r =
      Run("stimulus sum_of_sines --param duration_s=4 --param seed=7 --out '" + traj + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const api::Trial t = ReadCsv(traj);
  EXPECT_EQ(ChannelNames(t),
            (std::vector<std::string>{"t_s", "angle_deg", "velocity_deg_s", "accel_deg_s2"}));
  ASSERT_EQ(t.num_samples(), 801u);  // 0..4 s inclusive at 200 Hz

  const std::string stim = Path("rb.csv");
  ASSERT_EQ(Run("stimulus random_binary_dense --param duration_s=4 --out '" + stim + "'").exit_code,
            0);
  const std::string out = Path("motor.csv");
  r = Run("simulate --params '" + params_ + "' --stimulus '" + stim +
          "' --mode trajectory --trajectory '" + traj + "' --out '" + out + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const api::Trial sim = ReadCsv(out);
  EXPECT_EQ(ChannelNames(sim), kSimulationColumns);
  ASSERT_EQ(sim.num_samples(), 801u);  // the trajectory's samples, [0, 801 / 200 s)
  for (std::size_t i = 0; i < 801; i += 50) {
    EXPECT_NEAR((*sim.Values("angle_deg"))[i], (*t.Values("angle_deg"))[i], 1e-9) << i;
  }
}

TEST_F(ModelCliTest, StimulusParamsListAndStdout) {
  RunResult r = Run("stimulus impulses --param count=3 --param interval_s=0.5 --out -");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  api::Result<api::Trial> t = api::TrialFromCsv(r.out);
  ASSERT_TRUE(t.ok()) << t.status().ToString();
  int pulses = 0;
  for (double v : *t->Values("stim_ma")) pulses += v > 0.0;
  EXPECT_EQ(pulses, 3);
  EXPECT_EQ(t->num_samples(), 300u);  // 3 × 0.5 s at 200 Hz

  r = Run("stimulus --list");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("prediction_step"));
  EXPECT_THAT(r.out, HasSubstr("threshold_ma"));
  EXPECT_THAT(r.out, HasSubstr("mA"));
  EXPECT_THAT(r.out, HasSubstr("default 20"));
  EXPECT_THAT(r.out, HasSubstr("sum_of_sines (trajectory)"));
  EXPECT_THAT(r.out, HasSubstr("max_velocity_deg_s  unit deg/s"));
}

TEST_F(ModelCliTest, ExampleParameterSetIsAValidStartingPoint) {
  const std::string params = Path("example.json");
  ASSERT_EQ(Run("example --out '" + params + "'").exit_code, 0);
  const auto parsed = api::ParameterSetFromJson(nlohmann::json::parse(Read(params)));
  ASSERT_TRUE(parsed.ok()) << parsed.status().ToString();
  EXPECT_EQ(*parsed, model::ExampleParameterSet());
  const RunResult to_stdout = Run("example");
  EXPECT_EQ(to_stdout.exit_code, 0);
  EXPECT_EQ(to_stdout.out, Read(params));
  EXPECT_EQ(Run("example --out /nonexistent-dir/p.json").exit_code, 1);
}

TEST_F(ModelCliTest, HelpOnEveryCommand) {
  for (const std::string args :
       {"--help", "simulate --help", "stimulus --help", "identify --help", "example --help"}) {
    const RunResult r = Run(args);
    EXPECT_EQ(r.exit_code, 0) << args;
    EXPECT_THAT(r.out, HasSubstr("Usage")) << args;
    EXPECT_EQ(r.err, "");
  }
  EXPECT_THAT(Run("simulate --help").out, HasSubstr("--trajectory"));
  EXPECT_THAT(Run("stimulus --help").out, HasSubstr("--list"));
}

TEST_F(ModelCliTest, UsageErrorsExitWithTwo) {
  const std::string stim = Write("s.csv", "t_s,stim_ma\n0,0\n0.005,30\n");
  const std::string common = "--params '" + params_ + "' --stimulus '" + stim + "' ";
  ExpectError("", 2, "subcommand is required");
  ExpectError("fly", 2, "fly");
  ExpectError("simulate --stimulus '" + stim + "' --out x.csv", 2, "--params");
  ExpectError("simulate " + common, 2, "--out");
  ExpectError("simulate " + common + "--mode hover --out x.csv", 2, "hover");
  ExpectError("simulate " + common + "--integrator euler --out x.csv", 2, "euler");
  ExpectError("simulate " + common + "--model hill --out x.csv", 2, "hill");
  ExpectError("simulate " + common + "--angle-deg 200 --out x.csv", 2, "200");
  ExpectError("simulate " + common + "--angle-deg abc --out x.csv", 2, "abc");
  ExpectError("simulate " + common + "--mode trajectory --out x.csv", 2, "--trajectory");
  ExpectError("simulate " + common + "--trajectory t.csv --out x.csv", 2, "--mode trajectory");
  ExpectError("simulate " + common + "--out x.csv --frobnicate", 2, "frobnicate");
  ExpectError("simulate " + common + "--stops 110 10 --out x.csv", 2, "extension stop");
  ExpectError("simulate " + common + "--stops 10 --out x.csv", 2, "--stops");
  ExpectError("simulate " + common + "--stops 20 110 --angle-deg 15 --out x.csv", 2, "between");
  ExpectError("simulate " + common + "--mode isometric --stops 10 110 --out x.csv", 2,
              "free_swing");
  ExpectError("stimulus", 2, "generator NAME");
  ExpectError("stimulus prediction_step", 2, "--out");
  ExpectError("stimulus warp_drive --out x.csv", 2, "unknown generator 'warp_drive'");
  ExpectError("stimulus impulses --param count --out x.csv", 2, "expected name=value");
  ExpectError("stimulus impulses --param count=abc --out x.csv", 2, "not a finite number");
  ExpectError("stimulus impulses --param count=nan --out x.csv", 2, "not a finite number");
  ExpectError("stimulus impulses --param speed=3 --out x.csv", 2, "speed");
  ExpectError("stimulus impulses --param max_ma=500 --out x.csv", 2, "max_ma");
  ExpectError("stimulus impulses --param count=2.5 --out x.csv", 2, "count");
  ExpectError("stimulus impulses --param count=2 --param count=3 --out x.csv", 2, "more than once");
  ExpectError("stimulus --list impulses", 2, "--list");
}

TEST_F(ModelCliTest, BadInputDataExitsWithOne) {
  const std::string out = " --out '" + Path("o.csv") + "'";
  const std::string stim = Write("s.csv", "t_s,stim_ma\n0,0\n0.005,30\n");
  const auto simulate = [&](const std::string& params, const std::string& stimulus) {
    return "simulate --params '" + params + "' --stimulus '" + stimulus + "'" + out;
  };
  ExpectError(simulate(Path("missing.json"), stim), 1, "missing.json: cannot open");
  ExpectError(simulate(Write("bad.json", "{\"model\": "), stim), 1, "invalid JSON");

  nlohmann::json j = api::ParameterSetToJson(model::ExampleParameterSet());
  j["contraction"]["pole_per_s"] = -1.0;
  ExpectError(simulate(Write("neg.json", j.dump()), stim), 1, "contraction.pole_per_s");

  ExpectError(simulate(params_, Path("nope.csv")), 1, "nope.csv: cannot open");
  ExpectError(simulate(params_, Write("e.csv", "")), 1, "empty file");
  ExpectError(simulate(params_, Write("c.csv", "t_s,stim_ma\n0,1\n0.005,1,2\n")), 1,
              "line 3: expected 2 columns, found 3");
  ExpectError(simulate(params_, Write("n.csv", "t_s,stim_ma\n0,1\n0.005,x\n")), 1,
              "line 3, column 2 (stim_ma)");
  ExpectError(simulate(params_, Write("m.csv", "t_s,angle_deg\n0,1\n")), 1, "no stim_ma column");
  ExpectError(simulate(params_, Write("u.csv", "t_s,stim_ma\n0,1\n0.005,1\n0.02,1\n")), 1,
              "line 4: t_s 0.02 breaks uniform sampling");
  ExpectError(simulate(params_, Write("neg.csv", "t_s,stim_ma\n0,1\n0.005,-1\n")), 1,
              "line 3: stim_ma must be >= 0");
  ExpectError(simulate(params_, Write("t.csv", "t_s,stim_ma\n0,1\n0,1\n")), 1,
              "not greater than the previous");

  // Unwritable output.
  ExpectError("simulate --params '" + params_ + "' --stimulus '" + stim + "' --out '" +
                  Path("no/such/dir/o.csv") + "'",
              1, "cannot open for writing");

  // Trajectory file problems.
  const std::string traj_common =
      "simulate --params '" + params_ + "' --stimulus '" + stim + "' --mode trajectory" + out;
  ExpectError(traj_common + " --trajectory '" +
                  Write("tm.csv", "t_s,angle_deg,velocity_deg_s\n0,45,0\n0.005,45,0\n") + "'",
              1, "no accel_deg_s2 column");
  ExpectError(
      traj_common + " --trajectory '" +
          Write("tl.csv", "t_s,angle_deg,velocity_deg_s,accel_deg_s2\n1,45,0,0\n1.005,45,0,0\n") +
          "'",
      1, "t_s must start at 0");
}

}  // namespace
}  // namespace fesbench::cli
