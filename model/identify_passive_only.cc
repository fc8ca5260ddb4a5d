#include "model/identify_passive_only.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "model/extrapolate.h"
#include "model/identify_passive.h"
#include "model/identify_rapid.h"

namespace fesbench::model {

void MarkPassiveOnly(ParameterSet& params, bool irc_identified) {
  if (!irc_identified) {
    params.irc = PiecewiseLinear({0.0, 1.0}, {0.0, 0.0});  // no current activates
    params.provenance.irc_method = kNotIdentified;
  }
  params.provenance.active_method = kNotIdentified;
}

bool IsPassiveOnly(const ParameterSet& params) {
  return params.provenance.irc_method == kNotIdentified ||
         params.provenance.active_method == kNotIdentified;
}

std::size_t PendulumReleaseIndex(std::span<const double> t_s, std::span<const double> angle_deg,
                                 double departure_deg, double hold_deg, double min_hold_s) {
  if (t_s.size() != angle_deg.size()) {
    throw std::invalid_argument("PendulumReleaseIndex: t_s and angle_deg differ in length");
  }
  const std::size_t n = angle_deg.size();
  std::size_t held = 0;
  while (held < n && std::abs(angle_deg[held] - angle_deg.front()) <= hold_deg) ++held;
  if (held == n || t_s[held] - t_s.front() < min_hold_s) return 0;
  std::size_t i = held;
  while (i < n && std::abs(angle_deg[i] - angle_deg.front()) <= departure_deg) ++i;
  return i == n ? 0 : i;
}

TrialColumns TrialFromSample(const TrialColumns& tr, std::size_t from) {
  const std::size_t n = tr.size();
  TrialColumns out;
  for (std::vector<double> TrialColumns::*col :
       {&TrialColumns::t_s, &TrialColumns::stim_ma, &TrialColumns::angle_deg,
        &TrialColumns::velocity_deg_s, &TrialColumns::accel_deg_s2, &TrialColumns::torque_nm,
        &TrialColumns::activation, &TrialColumns::emg}) {
    const std::vector<double>& in = tr.*col;
    if (in.size() == n) (out.*col).assign(in.begin() + static_cast<std::ptrdiff_t>(from), in.end());
  }
  return out;
}

PassiveOnlyResult IdentifyPassiveOnly(std::span<const TrialColumns> trials,
                                      const PassiveOnlyOptions& options) {
  if (trials.empty()) throw std::invalid_argument("IdentifyPassiveOnly: no free-swing trials");
  if (!(options.inertia_kgm2 > 0.0) || !std::isfinite(options.inertia_kgm2)) {
    throw std::invalid_argument("IdentifyPassiveOnly: inertia_kgm2 must be finite and > 0");
  }

  // 0. Unstimulated swings only; 1. θ̇ and θ̈ over the whole recording (§5.1,
  //    so the release's are not edge values), then each from its release on,
  //    with a zero activation.
  std::vector<TrialColumns> swings;
  for (std::size_t k = 0; k < trials.size(); ++k) {
    TrialColumns full = trials[k];
    const std::size_t n = full.size();
    RequireColumn("IdentifyPassiveOnly", "angle_deg", full.angle_deg, n);
    if (full.stim_ma.empty()) full.stim_ma.assign(n, 0.0);
    RequireColumn("IdentifyPassiveOnly", "stim_ma", full.stim_ma, n);
    if (std::any_of(full.stim_ma.begin(), full.stim_ma.end(), [](double u) { return u != 0.0; })) {
      throw std::invalid_argument("IdentifyPassiveOnly: trial " + std::to_string(k) +
                                  " is stimulated; only unstimulated swings are passive");
    }
    if (full.velocity_deg_s.size() != n || full.accel_deg_s2.size() != n) AddKinematics(full);
    full.activation.assign(n, 0.0);
    swings.push_back(TrialFromSample(full, PendulumReleaseIndex(full.t_s, full.angle_deg)));
  }

  // 2. Eq. 4.35 with J known (§7.4.1), away from a bench's stops.
  PassiveOnlyResult out;
  ParameterSet& ps = out.parameters;
  ps = ExampleParameterSet();
  ps.model = ModelKind::kFull;
  double lo = INFINITY, hi = -INFINITY, vlo = INFINITY, vhi = -INFINITY;
  std::size_t samples = 0;
  std::vector<TrialColumns> free;
  for (const TrialColumns& tr : swings) {
    free.push_back(options.joint_limits ? WithoutStopContact(tr, *options.joint_limits,
                                                             options.stop_margin_deg,
                                                             options.stop_guard_s)
                                        : tr);
    const TrialColumns& f = free.back();
    for (std::size_t i = 0; i < f.size(); ++i) {
      lo = std::min(lo, f.angle_deg[i]);
      hi = std::max(hi, f.angle_deg[i]);
      vlo = std::min(vlo, f.velocity_deg_s[i]);
      vhi = std::max(vhi, f.velocity_deg_s[i]);
    }
    samples += f.size();
  }
  const PassiveResult pas = IdentifyPassiveKnownInertia(
      free, options.inertia_kgm2, options.angle, options.velocity,
      /*max_activation=*/0.5, options.relative_tolerance);
  ps.passive = pas.passive;
  out.report.Merge(pas.report);
  out.report.values["passive_only_samples"] = static_cast<double>(samples);

  Provenance& prov = ps.provenance;
  prov = {};
  prov.identified_range_deg["tau_pta"] = {lo, hi};
  prov.identified_range_deg_s["tau_ptv"] = {vlo, vhi};

  // 3. Beyond the visited angles and speeds (model/extrapolate.h), §6.5 reference.
  if (hi - lo >= 5.0) {
    const PassiveAngleForm form =
        FitPassiveAngleForm(ps.passive.torque_angle, lo, hi, options.mgl_prior_nm);
    ps.passive.torque_angle = ExtendPassiveAngle(ps.passive.torque_angle, form,
                                                 lo - options.extend_angle_deg,
                                                 hi + options.extend_angle_deg);
    out.report.fit_rms["tau_pta_form_nm"] = form.rms_nm;
    out.report.values["tau_pta_form_mgl_nm"] = form.mgl_nm();
    out.report.values["tau_pta_form_hang_deg"] = form.hang_deg();
  }
  const double vmax = options.extend_velocity_deg_s;
  ps.passive.torque_velocity =
      ExtendVelocityCurve(ps.passive.torque_velocity, vlo, vhi, -vmax, vmax, true);
  ps.passive = ReferencePassive(ps.passive);

  // 4. Output error on the knee angle (the active block has nothing to act
  //    on: with zero activation its ordinates stay at their start).
  if (options.refine_iterations > 0) {
    OutputErrorOptions oe;
    oe.iterations = options.refine_iterations;
    oe.prior_weight = options.refine_prior_weight;
    oe.joint_limits = options.joint_limits;
    const Provenance keep = prov;
    const OutputErrorResult refined = RefineOutputError(ps, swings, oe);
    ps = refined.parameters;
    ps.provenance = keep;
    out.report.Merge(refined.report);
  }

  prov.passive_method = "free_swing_known_inertia";
  MarkPassiveOnly(ps, /*irc_identified=*/false);
  prov.fit_rms = out.report.fit_rms;
  prov.warnings = out.report.warnings;
  return out;
}

}  // namespace fesbench::model
