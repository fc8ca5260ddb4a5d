#include "model/identify_rapid.h"

#include <Eigen/Core>
#include <stdexcept>
#include <string>

#include "model/conditioning.h"
#include "model/contraction.h"
#include "model/identify_least_squares.h"
#include "model/units.h"

namespace fesbench::model {

PulseTrain TrialPulses(const TrialColumns& trial, double pulse_rate_hz) {
  const std::size_t n = trial.t_s.size();
  if (n < 2) throw std::invalid_argument("TrialPulses: t_s needs at least 2 samples");
  RequireColumn("TrialPulses", "stim_ma", trial.stim_ma, n);
  if (!(pulse_rate_hz > 0.0)) throw std::invalid_argument("TrialPulses: pulse_rate_hz must be > 0");
  SampledSignal env;
  env.rate_hz = trial.SampleRateHz();
  env.t0_s = 0.0;
  env.values = trial.stim_ma;
  return PulsesFromEnvelope(env, pulse_rate_hz);
}

void AddKinematics(TrialColumns& trial) {
  std::vector<double> t(trial.t_s.size());
  for (std::size_t i = 0; i < t.size(); ++i) t[i] = trial.t_s[i] - trial.t_s.front();
  const SmoothingSplineFit fit = GcvSmoothingSpline(t, trial.angle_deg);
  trial.velocity_deg_s = fit.first;
  trial.accel_deg_s2 = fit.second;
}

PassiveResult IdentifyPassiveKnownInertia(std::span<const TrialColumns> trials, double inertia_kgm2,
                                          const BreakpointSpec& angle,
                                          const BreakpointSpec& velocity, double max_activation,
                                          double relative_tolerance) {
  const char* what = "IdentifyPassiveKnownInertia";
  if (!(inertia_kgm2 > 0.0) || !std::isfinite(inertia_kgm2)) {
    throw std::invalid_argument(std::string(what) + ": inertia_kgm2 must be finite and > 0");
  }
  std::vector<double> th, vel, acc;
  for (const TrialColumns& tr : trials) {
    const std::size_t n = tr.t_s.size();
    RequireColumn(what, "angle_deg", tr.angle_deg, n);
    RequireColumn(what, "velocity_deg_s", tr.velocity_deg_s, n);
    RequireColumn(what, "accel_deg_s2", tr.accel_deg_s2, n);
    RequireColumn(what, "activation", tr.activation, n);
    for (std::size_t i = 0; i < n; ++i) {
      if (tr.activation[i] > max_activation) continue;  // §5.4.3: passive samples only
      th.push_back(tr.angle_deg[i]);
      vel.push_back(tr.velocity_deg_s[i]);
      acc.push_back(tr.accel_deg_s2[i]);
    }
  }
  const std::vector<double> bp_a = ResolveBreakpoints(angle, th);
  const std::vector<double> bp_v = ResolveBreakpoints(velocity, vel);
  const auto ma = static_cast<Eigen::Index>(bp_a.size());
  const auto mv = static_cast<Eigen::Index>(bp_v.size());
  if (th.size() < static_cast<std::size_t>(ma + mv)) {
    throw std::invalid_argument(std::string(what) + ": fewer passive samples than parameters");
  }
  // §7.4.1 with Eq. 4.35: −J·θ̈ = τ_pta(θ) + τ_ptv(θ̇), θ̈ in rad/s².
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(th.size()), ma + mv);
  Eigen::VectorXd b(static_cast<Eigen::Index>(th.size()));
  for (std::size_t i = 0; i < th.size(); ++i) {
    const auto r = static_cast<Eigen::Index>(i);
    SetPwlBasisRow(a, r, 0, bp_a, th[i]);
    SetPwlBasisRow(a, r, ma, bp_v, vel[i]);
    b(r) = -inertia_kgm2 * DegToRad(acc[i]);
  }
  const LeastSquaresSolution sol = SolveTruncatedSvd(a, b, relative_tolerance);
  PassiveParams p;
  p.inertia_kgm2 = inertia_kgm2;
  p.torque_angle = PiecewiseLinear(bp_a, std::vector<double>(sol.c.data(), sol.c.data() + ma));
  p.torque_velocity =
      PiecewiseLinear(bp_v, std::vector<double>(sol.c.data() + ma, sol.c.data() + ma + mv));
  PassiveResult res;
  res.passive = ReferencePassive(p);
  res.report.fit_rms["free_swing_known_inertia_nm"] = sol.rms;
  res.report.values["free_swing_known_inertia_rank"] = sol.rank;
  res.report.values["free_swing_known_inertia_samples"] = static_cast<double>(th.size());
  // One constant is shared by τ_pta and τ_ptv (§6.5): rank ma + mv − 1 is full.
  if (sol.rank < ma + mv - 1) {
    res.report.warnings.push_back("free-swing passive (known J): rank " + std::to_string(sol.rank) +
                                  " of " + std::to_string(ma + mv - 1) + " (under-determined)");
  }
  for (auto& w : SupportWarnings("tau_pta", "deg", bp_a, BreakpointSupport(bp_a, th), 1.0))
    res.report.warnings.push_back(std::move(w));
  for (auto& w : SupportWarnings("tau_ptv", "deg/s", bp_v, BreakpointSupport(bp_v, vel), 1.0))
    res.report.warnings.push_back(std::move(w));
  return res;
}

RapidResult IdentifyRapid(const TrialColumns& isometric, const TrialColumns& passive,
                          const TrialColumns& active, const RapidOptions& options) {
  if (!(options.inertia_kgm2 > 0.0) || !std::isfinite(options.inertia_kgm2)) {
    throw std::invalid_argument("IdentifyRapid: inertia_kgm2 must be finite and > 0");
  }
  RapidResult out;
  ParameterSet& ps = out.parameters;
  ps.model = ModelKind::kFull;

  // 1. Contraction dynamics from the averaged impulses (§4.1, Eqs. 4.2/4.4)
  //    and the IRC by ramp correlation (§4.1.3, Eq. 4.5).
  const TrialColumns iso[] = {isometric};
  const ContractionResult contraction = IdentifyContraction(iso, options.contraction);
  ps.contraction = contraction.contraction;
  out.report.Merge(contraction.report);
  const IrcResult irc = IdentifyIrc(IrcMethod::kRampCorrelation, isometric, options.irc);
  ps.irc = irc.irc;
  out.report.Merge(irc.report);
  out.report.values["irc_torque_scale_nm"] = irc.torque_scale_nm;

  // 2. Kinematics and activation of the free-swing trials.
  TrialColumns swing[] = {passive, active};
  for (TrialColumns& tr : swing) {
    AddKinematics(tr);
    tr.activation = ActivationAt(ps.contraction, ps.irc, TrialPulses(tr, options.pulse_rate_hz),
                                 options.pulse_rate_hz, [&] {
                                   std::vector<double> t(tr.t_s.size());
                                   for (std::size_t i = 0; i < t.size(); ++i)
                                     t[i] = tr.t_s[i] - tr.t_s.front();
                                   return t;
                                 }());
  }

  // 3. Passive with known inertia (§7.4.1), then active (Eq. 4.40).
  const PassiveResult pas = IdentifyPassiveKnownInertia(
      swing, options.inertia_kgm2, options.passive_angle, options.passive_velocity,
      options.max_passive_activation, options.relative_tolerance);
  ps.passive = pas.passive;
  out.report.Merge(pas.report);
  ActiveOptions ao;
  ao.angle = options.active_angle;
  ao.velocity = options.active_velocity;
  ao.min_activation = options.max_passive_activation;
  ao.relative_tolerance = options.relative_tolerance;
  const ActiveResult act = IdentifyActive(swing, ps.passive, ao);
  ps.active = act.active;
  out.report.Merge(act.report);

  ps.provenance.irc_method = std::string(IrcMethodName(IrcMethod::kRampCorrelation));
  ps.provenance.passive_method = "free_swing_known_inertia";
  ps.provenance.active_method = "log_least_squares";
  ps.provenance.fit_rms = out.report.fit_rms;
  ps.provenance.warnings = out.report.warnings;
  return out;
}

}  // namespace fesbench::model
