#include "clients/model_cli/simulate_command.h"

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "api/model_call.h"
#include "clients/model_cli/cli_io.h"
#include "clients/model_cli/commands.h"
#include "model/integrators.h"

namespace fesbench::cli {

std::string_view SimulateModeName(SimulateMode mode) {
  switch (mode) {
    case SimulateMode::kFreeSwing:
      return "free_swing";
    case SimulateMode::kIsometric:
      return "isometric";
    case SimulateMode::kTrajectory:
      return "trajectory";
  }
  return "unknown";
}

std::optional<SimulateMode> ParseSimulateMode(std::string_view name) {
  for (SimulateMode m :
       {SimulateMode::kFreeSwing, SimulateMode::kIsometric, SimulateMode::kTrajectory}) {
    if (SimulateModeName(m) == name) return m;
  }
  return std::nullopt;
}

namespace {

model::SimulationResult Simulate(const model::ParameterSet& params,
                                 const model::SampledSignal& envelope_ma,
                                 const model::PulseTrain& pulses, SimulateMode mode,
                                 double angle_deg, const model::Trajectory* trajectory,
                                 double trajectory_end_s, model::SimulationOptions& options) {
  switch (mode) {
    case SimulateMode::kFreeSwing:
      if (!options.duration_s) options.duration_s = envelope_ma.EndTime();
      options.initial_angle_deg = angle_deg;
      return model::SimulateFreeSwing(params, pulses, options);
    case SimulateMode::kIsometric:
      if (!options.duration_s) options.duration_s = envelope_ma.EndTime();
      return model::SimulateIsometric(params, pulses, angle_deg, options);
    case SimulateMode::kTrajectory:
      if (!options.duration_s) options.duration_s = trajectory_end_s;
      return model::SimulateTrajectory(params, pulses, *trajectory, options);
  }
  return {};
}

}  // namespace

api::Result<api::Trial> RunSimulation(const model::ParameterSet& params,
                                      const model::SampledSignal& envelope_ma, SimulateMode mode,
                                      double angle_deg, const model::Trajectory* trajectory,
                                      double trajectory_end_s, model::SimulationOptions options) {
  if (mode == SimulateMode::kTrajectory && trajectory == nullptr) {
    return api::Status::InvalidArgument("trajectory mode needs a trajectory");
  }
  api::Result<model::PulseTrain> pulsed =
      api::CallModel([&] { return model::PulsesFromEnvelope(envelope_ma, options.pulse_rate_hz); });
  if (!pulsed.ok()) return pulsed.status();
  const model::PulseTrain& pulses = *pulsed;
  api::Result<model::SimulationResult> simulated = api::CallModel([&] {
    return Simulate(params, envelope_ma, pulses, mode, angle_deg, trajectory, trajectory_end_s,
                    options);
  });
  if (!simulated.ok()) return simulated.status();
  model::SimulationResult& r = *simulated;
  api::Trial trial;
  trial.name = "simulated_" + std::string(SimulateModeName(mode));
  trial.sample_rate_hz = options.output_rate_hz;
  trial.SetChannel("t_s", std::move(r.t_s));
  trial.SetChannel("stim_ma", std::move(r.stim_ma));
  trial.SetChannel("angle_deg", std::move(r.angle_deg));
  trial.SetChannel("velocity_deg_s", std::move(r.velocity_deg_s));
  trial.SetChannel("accel_deg_s2", std::move(r.accel_deg_s2));
  trial.SetChannel("torque_nm", std::move(r.torque_nm));
  trial.SetChannel("activation", std::move(r.activation));
  api::PulseRecord record;
  record.pulse_rate_hz = options.pulse_rate_hz;
  for (const model::Pulse& p : pulses) record.Append(p.t_s, p.stim_ma);
  trial.pulses = std::move(record);
  return trial;
}

namespace {

struct SimulateArgs {
  std::string params_path;
  std::string stimulus_path;
  std::string mode = "free_swing";
  std::string model;
  std::string integrator = "rk4";
  double angle_deg = 90.0;
  std::string trajectory_path;
  std::string out_path;
  std::string format;
  double duration_s = 0.0;  // 0: unset
  double pulse_rate_hz = model::kDefaultPulseRateHz;
  double step_s = 1e-3;
  std::vector<double> stops_deg;  // empty, or {extension stop, flexion stop}
};

void RunSimulateCommand(const SimulateArgs& args, CliContext& context) {
  const SimulateMode mode = *ParseSimulateMode(args.mode);  // checked by CLI11
  if (mode == SimulateMode::kTrajectory && args.trajectory_path.empty()) {
    throw CliError::Usage("--mode trajectory needs --trajectory T.csv");
  }
  if (mode != SimulateMode::kTrajectory && !args.trajectory_path.empty()) {
    throw CliError::Usage("--trajectory is only used with --mode trajectory");
  }
  const TableFormat format = ResolveTableFormat(args.format, args.out_path);

  model::SimulationOptions options;
  options.integrator = *model::ParseIntegratorKind(args.integrator);  // checked by CLI11
  options.step_s = args.step_s;
  options.pulse_rate_hz = args.pulse_rate_hz;
  if (args.duration_s > 0.0) options.duration_s = args.duration_s;
  if (!args.model.empty()) options.model_kind = *model::ParseModelKind(args.model);
  if (!args.stops_deg.empty()) {
    if (mode != SimulateMode::kFreeSwing) throw CliError::Usage("--stops is for --mode free_swing");
    const double lo = args.stops_deg[0], hi = args.stops_deg[1];
    if (!(lo < hi))
      throw CliError::Usage("--stops: the extension stop must be below the flexion stop");
    if (args.angle_deg < lo || args.angle_deg > hi) {
      throw CliError::Usage("--angle-deg: the initial angle must lie between the --stops");
    }
    options.joint_limits = model::JointLimits{lo, hi};
  }

  const model::ParameterSet params = ReadParameterSetFile(args.params_path);
  const api::Trial stimulus = ReadUniformCsv(args.stimulus_path, "stimulus", {"stim_ma"});
  const model::SampledSignal envelope = ChannelAsSignal(stimulus, "stim_ma");
  if (envelope.t0_s < 0.0) {
    throw CliError::BadInput("stimulus " + args.stimulus_path +
                             ": line 2: t_s must start at or after 0");
  }
  for (std::size_t i = 0; i < envelope.size(); ++i) {
    if (envelope.values[i] < 0.0) {
      throw CliError::BadInput("stimulus " + args.stimulus_path + ": line " +
                               std::to_string(i + 2) + ": stim_ma must be >= 0");
    }
  }

  std::unique_ptr<model::SampledTrajectory> trajectory;
  double trajectory_end_s = 0.0;
  if (mode == SimulateMode::kTrajectory) {
    const api::Trial table = ReadUniformCsv(args.trajectory_path, "trajectory",
                                            {"angle_deg", "velocity_deg_s", "accel_deg_s2"});
    const double t0 = table.Values(api::kTimeChannel)->front();
    if (std::abs(t0) > 1e-9) {
      throw CliError::BadInput("trajectory " + args.trajectory_path +
                               ": line 2: t_s must start at 0");
    }
    api::Result<std::unique_ptr<model::SampledTrajectory>> sampled = api::CallModel([&] {
      return std::make_unique<model::SampledTrajectory>(
          table.sample_rate_hz, *table.Values("angle_deg"), *table.Values("velocity_deg_s"),
          *table.Values("accel_deg_s2"));
    });
    if (!sampled.ok()) {
      throw CliError::BadInput("trajectory " + args.trajectory_path + ": " +
                               sampled.status().message());
    }
    trajectory = std::move(sampled).value();
    // The samples cover [0, N / rate), like a recording.
    trajectory_end_s = static_cast<double>(table.num_samples()) / table.sample_rate_hz;
  }

  // Invalid combinations of data (e.g. a variant whose fields the parameter
  // set lacks) and integrator failures.
  const api::Result<api::Trial> result = RunSimulation(params, envelope, mode, args.angle_deg,
                                                       trajectory.get(), trajectory_end_s, options);
  if (!result.ok()) throw CliError::BadInput("simulation failed: " + result.status().message());
  WriteTable(*result, args.out_path, format, context);
}

}  // namespace

void RegisterSimulateCommand(CLI::App& app, CliContext& context) {
  auto args = std::make_shared<SimulateArgs>();
  CLI::App* sub = app.add_subcommand(
      "simulate",
      "Simulate a parameter set driven by a stimulation envelope; writes t_s, stim_ma, "
      "angle_deg, velocity_deg_s, accel_deg_s2, torque_nm, activation at 200 Hz.");
  std::vector<std::string> model_names;
  for (model::ModelKind k : model::AllModelKinds()) {
    model_names.emplace_back(model::ModelKindName(k));
  }
  sub->add_option("--params", args->params_path, "parameter set JSON (docs/MODEL.md)")->required();
  sub->add_option("--stimulus", args->stimulus_path,
                  "stimulus CSV with columns t_s, stim_ma (uniformly sampled envelope, mA)")
      ->required();
  sub->add_option("--mode", args->mode, "bench mode")
      ->check(CLI::IsMember({"free_swing", "isometric", "trajectory"}))
      ->capture_default_str();
  sub->add_option("--model", args->model, "model variant overriding the parameter set's")
      ->check(CLI::IsMember(model_names));
  sub->add_option("--integrator", args->integrator, "integrator of the mechanics")
      ->check(CLI::IsMember({"rk4", "adaptive"}))
      ->capture_default_str();
  sub->add_option("--angle-deg", args->angle_deg,
                  "isometric: locked knee angle; free swing: initial angle (deg, 0-180)")
      ->check(CLI::Range(0.0, 180.0))
      ->capture_default_str();
  sub->add_option("--stops", args->stops_deg,
                  "free swing: the knee's stops MIN MAX in deg (e.g. 10 110, the bench's range "
                  "of motion, as the server's predictions); default none (the thesis's model)")
      ->expected(2)
      ->check(CLI::Range(0.0, 180.0));
  sub->add_option("--trajectory", args->trajectory_path,
                  "trajectory mode: CSV with t_s, angle_deg, velocity_deg_s, accel_deg_s2 "
                  "(uniform, from t_s = 0)");
  sub->add_option("--duration-s", args->duration_s,
                  "simulated span in s (default: the stimulus, or the trajectory)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--pulse-rate-hz", args->pulse_rate_hz, "stimulator pulse rate (Hz)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  sub->add_option("--step-s", args->step_s, "RK4 step (s)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  sub->add_option("--out", args->out_path, "output file ('-' for standard output)")->required();
  sub->add_option("--format", args->format,
                  "output format (default from the --out extension: .sto, .json, else csv)")
      ->check(CLI::IsMember({"csv", "sto", "json"}));
  sub->callback([args, &context] { RunSimulateCommand(*args, context); });
}

}  // namespace fesbench::cli
