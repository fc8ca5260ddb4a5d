#include "clients/model_cli/identify_command.h"

#include <charconv>
#include <cmath>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <stdexcept>

#include "api/model_call.h"
#include "api/parameter_set_json.h"
#include "api/trial.h"
#include "clients/model_cli/cli_io.h"
#include "clients/model_cli/commands.h"
#include "model/conditioning.h"
#include "model/contraction.h"
#include "model/identify_active.h"
#include "model/identify_isometric.h"
#include "model/identify_passive.h"
#include "model/identify_rapid.h"
#include "model/identify_simplified.h"
#include "model/quality.h"
#include "model/signal.h"

namespace fesbench::cli {
namespace {

// Options by name; every key must be read by the method, or it is reported.
class Options {
 public:
  explicit Options(const std::map<std::string, std::string>& values) : values_(values) {}

  std::optional<std::string> Text(const std::string& key) {
    used_.insert(key);
    const auto it = values_.find(key);
    if (it == values_.end()) return std::nullopt;
    return it->second;
  }
  std::optional<double> Number(const std::string& key) {
    const auto text = Text(key);
    if (!text) return std::nullopt;
    return ParseNumber(key, *text);
  }
  double Number(const std::string& key, double fallback) { return Number(key).value_or(fallback); }
  // "N" (count) or "x1,x2,..." (explicit breakpoints).
  void Breakpoints(const std::string& key, model::BreakpointSpec& spec) {
    const auto text = Text(key);
    if (!text) return;
    if (text->find(',') == std::string::npos) {
      const double n = ParseNumber(key, *text);
      if (n < 2 || n != std::floor(n))
        throw CliError::Usage("--option " + key + ": count must be an integer >= 2");
      spec.count = static_cast<int>(n);
      spec.explicit_x.clear();
      return;
    }
    std::vector<double> xs;
    std::size_t start = 0;
    while (start <= text->size()) {
      const std::size_t comma = text->find(',', start);
      const std::string part =
          text->substr(start, comma == std::string::npos ? std::string::npos : comma - start);
      xs.push_back(ParseNumber(key, part));
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
    for (std::size_t i = 1; i < xs.size(); ++i) {
      if (!(xs[i] > xs[i - 1]))
        throw CliError::Usage("--option " + key + ": breakpoints must increase");
    }
    spec.explicit_x = std::move(xs);
  }
  void RequireAllUsed() const {
    for (const auto& [k, v] : values_) {
      if (!used_.count(k))
        throw CliError::Usage("--option " + k + ": not an option of this method");
    }
  }

 private:
  static double ParseNumber(const std::string& key, const std::string& text) {
    double v = 0.0;
    const auto [p, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
    if (ec != std::errc() || p != text.data() + text.size() || !std::isfinite(v)) {
      throw CliError::Usage("--option " + key + "=" + text + ": not a number");
    }
    return v;
  }
  const std::map<std::string, std::string>& values_;
  std::set<std::string> used_;
};

void RequireTrials(std::string_view method, const std::vector<model::TrialColumns>& trials,
                   std::size_t n) {
  if (trials.size() < n) {
    throw CliError::Usage(std::string(method) + " needs " + std::to_string(n) + " --trial file(s)");
  }
}

void Condition(std::vector<model::TrialColumns>& trials, Options& opt,
               model::IdentifyReport& report) {
  if (const auto n = opt.Number("offset_samples")) {
    for (auto& tr : trials) {
      if (!tr.torque_nm.empty())
        tr.torque_nm = model::RemoveTorqueOffset(tr.torque_nm, static_cast<std::size_t>(*n));
    }
  }
  if (const auto idx = opt.Number("accel_calibration_trial")) {
    const auto k = static_cast<std::size_t>(*idx);
    if (k >= trials.size())
      throw CliError::Usage("--option accel_calibration_trial: no such trial");
    const auto table =
        model::AccelerometerCalibration(trials[k].t_s, trials[k].angle_deg, trials[k].accel_deg_s2);
    for (auto& tr : trials) {
      if (tr.accel_deg_s2.size() == tr.size())
        tr.accel_deg_s2 = model::CorrectAcceleration(table, tr.angle_deg, tr.accel_deg_s2);
    }
    report.values["accel_calibration_points"] = static_cast<double>(table.size());
  }
  if (const auto mode = opt.Text("derive_kinematics")) {
    if (*mode != "gcv")
      throw CliError::Usage("--option derive_kinematics: only 'gcv' is supported");
    for (auto& tr : trials) {
      const auto fit = model::GcvSmoothingSpline(tr.t_s, tr.angle_deg);
      tr.velocity_deg_s = fit.first;
      tr.accel_deg_s2 = fit.second;
      report.values["gcv_effective_dof"] = fit.effective_dof;
    }
  }
}

void EnsureActivation(std::vector<model::TrialColumns>& trials, const model::ParameterSet& p,
                      double pulse_rate_hz) {
  for (auto& tr : trials) {
    if (tr.activation.size() == tr.size()) continue;
    if (tr.stim_ma.size() != tr.size()) continue;  // the method reports the missing column
    model::SampledSignal env;
    env.rate_hz = tr.SampleRateHz();
    env.t0_s = tr.t_s.front();
    env.values = tr.stim_ma;
    const auto pulses = model::PulsesFromEnvelope(env, pulse_rate_hz);
    tr.activation = model::ActivationAt(p.contraction, p.irc, pulses, pulse_rate_hz, tr.t_s);
  }
}

// The output-error step of the rapid routine (model/identify_rapid.h, beyond
// the thesis) on any free-swing trials: τ_pta, τ_ptv, f_ata, f_atv and
// τ_scale of `in` refined on the knee angle (Eq. 6.9). iterations=0 only
// evaluates: the report's output_error_deg is then the set's E_RMS on the
// trials, stops included when min_angle_deg/max_angle_deg are given.
model::ParameterSet RefineByOutputError(std::vector<model::TrialColumns>& trials,
                                        const model::ParameterSet& in, Options& opt,
                                        double pulse_rate, model::IdentifyReport& report) {
  model::OutputErrorOptions o;
  o.pulse_rate_hz = pulse_rate;
  const double iterations = opt.Number("iterations", o.iterations);
  if (!(iterations >= 0.0) || iterations != std::floor(iterations) || iterations > 1000.0) {
    throw CliError::Usage("--option iterations: an integer from 0 to 1000");
  }
  o.iterations = static_cast<int>(iterations);
  o.prior_weight = opt.Number("prior_weight", o.prior_weight);
  if (!(o.prior_weight >= 0.0)) throw CliError::Usage("--option prior_weight: must be >= 0");
  const auto lo = opt.Number("min_angle_deg");
  const auto hi = opt.Number("max_angle_deg");
  if (lo.has_value() != hi.has_value()) {
    throw CliError::Usage("--option min_angle_deg and max_angle_deg: give both stops or neither");
  }
  if (lo) {
    if (!(*lo < *hi)) throw CliError::Usage("--option min_angle_deg: must be < max_angle_deg");
    o.joint_limits = model::JointLimits{*lo, *hi};
  }
  for (model::TrialColumns& tr : trials) {
    if (tr.velocity_deg_s.size() != tr.size()) model::AddKinematics(tr);
  }
  model::OutputErrorResult r = model::RefineOutputError(in, trials, o);
  report.Merge(r.report);
  return std::move(r.parameters);
}

// The passive block by `method` (§4.2): sequential from a positions and a
// velocities trial, simultaneous, or free swing with τ_pta from `in`.
model::ParameterSet IdentifyPassiveBlock(model::PassiveMethod method,
                                         std::vector<model::TrialColumns>& trials,
                                         const model::ParameterSet& in, Options& opt,
                                         double pulse_rate, model::IdentifyReport& report) {
  using namespace model;
  const std::string name = "passive_" + std::string(PassiveMethodName(method));
  PassiveResult r;
  switch (method) {
    case PassiveMethod::kSequential: {
      RequireTrials(name, trials, 2);
      SequentialPassiveOptions o;
      o.body_mass_kg = opt.Number("body_mass_kg");
      o.leg_length_m = opt.Number("leg_length_m");
      o.inertia_kgm2 = opt.Number("inertia_kgm2", in.passive.inertia_kgm2);
      o.use_last_s = opt.Number("use_last_s", o.use_last_s);
      r = IdentifyPassiveSequential(trials[0], trials[1], o);
      break;
    }
    case PassiveMethod::kSimultaneous: {
      RequireTrials(name, trials, 1);
      SimultaneousPassiveOptions o;
      opt.Breakpoints("angle_breakpoints", o.angle);
      opt.Breakpoints("velocity_breakpoints", o.velocity);
      r = IdentifyPassiveSimultaneous(trials, o);
      break;
    }
    case PassiveMethod::kFreeSwing: {
      RequireTrials(name, trials, 1);
      FreeSwingPassiveOptions o;
      opt.Breakpoints("velocity_breakpoints", o.velocity);
      o.max_activation = opt.Number("max_activation", o.max_activation);
      EnsureActivation(trials, in, pulse_rate);
      r = IdentifyPassiveFreeSwing(trials, in.passive.torque_angle, o);
      break;
    }
  }
  ParameterSet out = in;
  out.passive = r.passive;
  out.provenance.passive_method = std::string(PassiveMethodName(method));
  report.Merge(r.report);
  return out;
}

model::ParameterSet Dispatch(std::string_view method, std::vector<model::TrialColumns>& trials,
                             const model::ParameterSet& in, Options& opt,
                             model::IdentifyReport& report) {
  using namespace model;
  ParameterSet out = in;
  const double pulse_rate = opt.Number("pulse_rate_hz", kDefaultPulseRateHz);
  TwitchOptions twitch;
  twitch.window_s = opt.Number("window_s", twitch.window_s);
  twitch.baseline_samples = static_cast<std::size_t>(opt.Number("baseline_samples", 10));

  if (method == "contraction") {
    RequireTrials(method, trials, 1);
    ContractionOptions o;
    o.twitch = twitch;
    o.order = static_cast<int>(opt.Number("order", 3));
    if (const auto m = opt.Text("pole_method")) {
      const std::optional<PoleMethod> pole = PoleMethodFromName(*m);
      if (!pole) throw CliError::Usage("--option pole_method: peak or least_squares");
      o.method = *pole;
    }
    const ContractionResult r = IdentifyContraction(trials, o);
    out.contraction = r.contraction;
    report.Merge(r.report);
    return out;
  }
  if (method.starts_with("irc_")) {
    RequireTrials(method, trials, 1);
    IrcOptions o;
    o.twitch = twitch;
    o.step_average_s = opt.Number("step_average_s", o.step_average_s);
    o.ramp_points = static_cast<int>(opt.Number("ramp_points", o.ramp_points));
    o.max_lag_s = opt.Number("max_lag_s", o.max_lag_s);
    o.lowpass_hz = opt.Number("lowpass_hz", o.lowpass_hz);
    o.guard = opt.Number("guard", o.guard);
    o.ideal.order = static_cast<int>(opt.Number("ideal_order", o.ideal.order));
    o.ideal.pole_per_s = opt.Number("ideal_pole_per_s", 0.0);
    const std::optional<IrcMethod> m = IrcMethodFromName(method.substr(4));
    if (!m) throw CliError::Usage("unknown identification method " + std::string(method));
    const IrcResult r = IdentifyIrc(*m, trials.front(), o);
    out.irc = r.irc;
    out.active.torque_scale_nm = r.torque_scale_nm;  // isometric full scale at 90°
    out.provenance.irc_method = std::string(IrcMethodName(*m));
    report.Merge(r.report);
    return out;
  }
  if (method.starts_with("passive_")) {
    const std::optional<PassiveMethod> m = PassiveMethodFromName(method.substr(8));
    if (!m) throw CliError::Usage("unknown identification method " + std::string(method));
    return IdentifyPassiveBlock(*m, trials, in, opt, pulse_rate, report);
  }
  if (method == "output_error") {
    RequireTrials(method, trials, 1);
    return RefineByOutputError(trials, in, opt, pulse_rate, report);
  }
  ActiveOptions ao;
  opt.Breakpoints("angle_breakpoints", ao.angle);
  opt.Breakpoints("velocity_breakpoints", ao.velocity);
  ao.min_activation = opt.Number("min_activation", ao.min_activation);
  if (method == "active") {
    RequireTrials(method, trials, 1);
    EnsureActivation(trials, in, pulse_rate);
    const ActiveResult r = IdentifyActive(trials, in.passive, ao);
    out.model = ModelKind::kFull;
    out.active = r.active;
    out.provenance.active_method = "log_least_squares";
    report.Merge(r.report);
    return out;
  }
  const auto kind = ParseModelKind(method);
  if (!kind || *kind == ModelKind::kFull)
    throw CliError::Usage("unknown identification method " + std::string(method));
  RequireTrials(method, trials, 1);
  EnsureActivation(trials, in, pulse_rate);
  SimplifiedOptions so;
  so.active = ao;
  so.velocity = ao.velocity;
  so.iterations = static_cast<int>(opt.Number("iterations", so.iterations));
  const SimplifiedResult r = IdentifySimplified(*kind, trials, in, so);
  out = r.params;
  out.provenance.active_method = std::string(method);
  report.Merge(r.report);
  return out;
}

struct IdentifyArgs {
  std::string method;
  std::vector<std::string> trials;
  std::string params_in;
  std::vector<std::string> options;
  std::string out_path;
};

void RunIdentifyCommand(const IdentifyArgs& args, CliContext& context) {
  std::map<std::string, std::string> options;
  for (const std::string& kv : args.options) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos || eq == 0)
      throw CliError::Usage("--option " + kv + ": expected k=v");
    options[kv.substr(0, eq)] = kv.substr(eq + 1);
  }
  model::ParameterSet params_in;
  model::IdentifyReport report;
  if (!args.params_in.empty()) {
    params_in = ReadParameterSetFile(args.params_in);
  } else {
    params_in = model::ExampleParameterSet();
    report.warnings.push_back(
        "no --params-in: fields this method does not identify are the example parameter set's");
  }
  std::vector<model::TrialColumns> trials;
  for (const std::string& path : args.trials) {
    api::Result<std::string> text = api::ReadTextFile(path);
    if (!text.ok()) throw CliError::BadInput("trial " + text.status().message());
    api::Result<api::Trial> table = api::TrialFromCsv(*text);
    if (!table.ok()) throw CliError::BadInput("trial " + path + ": " + table.status().message());
    trials.push_back(api::ToTrialColumns(*table));
    if (table->emg && table->emg->Values("emg")) {
      // Refused (too short an EMG recording): nothing to compare.
      const api::Result<model::EmgComparison> c = api::CallModel([&] {
        return model::CompareEmgPrePost(*table->emg->Values("emg"), table->emg->sample_rate_hz);
      });
      if (c.ok() && c->voluntary_contraction) {
        report.warnings.push_back("trial " + path + ": EMG differs before and after (ratio " +
                                  std::to_string(c->ratio) + "): voluntary contraction? (§5.2.1)");
      }
    }
  }
  model::ParameterSet out =
      RunIdentify(args.method, std::move(trials), params_in, options, &report);
  const nlohmann::json json = api::ParameterSetToJson(out);
  if (api::Status s = api::WriteTextFile(args.out_path, json.dump(2) + "\n"); !s.ok()) {
    throw CliError::BadInput(s.message());
  }
  nlohmann::json rep;
  rep["method"] = args.method;
  rep["fit_rms"] = report.fit_rms;
  rep["values"] = report.values;
  rep["warnings"] = report.warnings;
  // One line: the summary, and easy to grep or parse in scripts.
  context.out << rep.dump() << "\n";
}

}  // namespace

const std::vector<std::string>& IdentifyMethodNames() {
  // The block methods are the model's own names, prefixed by their block.
  static const std::vector<std::string> kNames = [] {
    std::vector<std::string> names = {"contraction"};
    for (model::IrcMethod m : model::kIrcMethods) {
      names.push_back("irc_" + std::string(model::IrcMethodName(m)));
    }
    for (model::PassiveMethod m : model::kPassiveMethods) {
      names.push_back("passive_" + std::string(model::PassiveMethodName(m)));
    }
    names.push_back("active");
    names.push_back("output_error");
    for (model::ModelKind kind : model::AllModelKinds()) {
      if (kind != model::ModelKind::kFull) names.emplace_back(model::ModelKindName(kind));
    }
    return names;
  }();
  return kNames;
}

model::ParameterSet RunIdentify(std::string_view method, std::vector<model::TrialColumns> trials,
                                const model::ParameterSet& params_in,
                                const std::map<std::string, std::string>& options,
                                model::IdentifyReport* report) {
  model::IdentifyReport local;
  model::IdentifyReport& rep = report ? *report : local;
  Options opt(options);
  api::Result<model::ParameterSet> fitted = api::CallModel([&] {
    Condition(trials, opt, rep);
    return Dispatch(method, trials, params_in, opt, rep);
  });
  if (!fitted.ok())
    throw CliError::BadInput(std::string(method) + ": " + fitted.status().message());
  model::ParameterSet out = *std::move(fitted);
  opt.RequireAllUsed();
  for (const auto& [k, v] : rep.fit_rms) out.provenance.fit_rms[k] = v;
  out.provenance.warnings.insert(out.provenance.warnings.end(), rep.warnings.begin(),
                                 rep.warnings.end());
  return out;
}

void RegisterIdentifyCommand(CLI::App& app, CliContext& context) {
  auto args = std::make_shared<IdentifyArgs>();
  CLI::App* sub = app.add_subcommand(
      "identify",
      "Identify model parameters from trial CSVs (thesis ch. 4); writes the parameter set and "
      "prints the report (fit RMS, figures, warnings) as JSON.");
  sub->add_option("method", args->method, "identification method")
      ->required()
      ->check(CLI::IsMember(IdentifyMethodNames()));
  sub->add_option("--trial", args->trials,
                  "trial CSV (t_s and the channels the method needs); repeatable")
      ->required();
  sub->add_option("--params-in", args->params_in,
                  "parameter set JSON to start from (passive set for active/free swing, IRC and "
                  "contraction for activation)");
  sub->add_option("--option", args->options, "method option k=v; repeatable");
  sub->add_option("--out", args->out_path, "output parameter set JSON")->required();
  sub->callback([args, &context] { RunIdentifyCommand(*args, context); });
}

}  // namespace fesbench::cli
