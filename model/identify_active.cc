#include "model/identify_active.h"

#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "model/identify_least_squares.h"
#include "model/quality.h"
#include "model/units.h"

namespace fesbench::model {

std::vector<double> ActiveTorque(const TrialColumns& trial, const PassiveParams& passive,
                                 bool use_measured_torque) {
  const char* what = "ActiveTorque";
  const std::size_t n = trial.size();
  RequireColumn(what, "angle_deg", trial.angle_deg, n);
  RequireColumn(what, "velocity_deg_s", trial.velocity_deg_s, n);
  RequireColumn(what, "accel_deg_s2", trial.accel_deg_s2, n);
  if (use_measured_torque) RequireColumn(what, "torque_nm", trial.torque_nm, n);
  if (passive.torque_angle.empty() || passive.torque_velocity.empty()) {
    throw std::invalid_argument("ActiveTorque: passive curves are empty");
  }
  std::vector<double> out(n);
  std::size_t segment_v = 0, segment_a = 0;  // the curves' segments along the trial
  for (std::size_t i = 0; i < n; ++i) {
    // Eq. 4.36 (τ_passive) and Eq. 4.38.
    const double passive_nm = passive.inertia_kgm2 * DegToRad(trial.accel_deg_s2[i]) +
                              passive.torque_velocity(trial.velocity_deg_s[i], segment_v) +
                              passive.torque_angle(trial.angle_deg[i], segment_a);
    out[i] = (use_measured_torque ? trial.torque_nm[i] : 0.0) - passive_nm;
  }
  return out;
}

ActiveResult IdentifyActive(std::span<const TrialColumns> trials, const PassiveParams& passive,
                            const ActiveOptions& options) {
  const char* what = "IdentifyActive";
  std::vector<double> angle, vel, act, tau;
  std::size_t skipped_nonpositive = 0;
  for (const TrialColumns& tr : trials) {
    RequireColumn(what, "activation", tr.activation, tr.size());
    const auto t_act = ActiveTorque(tr, passive, options.use_measured_torque);
    for (std::size_t i = 0; i < tr.size(); ++i) {
      if (tr.activation[i] < options.min_activation) continue;  // §5.4.4
      if (!(t_act[i] > 0.0)) {
        ++skipped_nonpositive;
        continue;
      }
      angle.push_back(tr.angle_deg[i]);
      vel.push_back(tr.velocity_deg_s[i]);
      act.push_back(tr.activation[i]);
      tau.push_back(t_act[i]);
    }
  }
  const std::size_t total = tau.size();
  if (total == 0) throw std::invalid_argument(std::string(what) + ": no active samples");
  const auto bp_a = ResolveBreakpoints(options.angle, angle);
  const auto bp_v = ResolveBreakpoints(options.velocity, vel);
  const Eigen::Index ma = static_cast<Eigen::Index>(bp_a.size());
  const Eigen::Index mv = static_cast<Eigen::Index>(bp_v.size());
  if (total < static_cast<std::size_t>(ma + mv + 1)) {
    throw std::invalid_argument(std::string(what) + ": fewer active samples than parameters");
  }
  // Eq. 4.40 (its rows reduced per cell of the two bases as they come,
  // PwlLeastSquares), with the smoothness rows (ActiveOptions::smoothness)
  // below.
  const Eigen::Index bends = options.smoothness > 0.0 ? std::max<Eigen::Index>(0, ma - 2) +
                                                            std::max<Eigen::Index>(0, mv - 2)
                                                      : 0;
  PwlLeastSquares design(bp_a, bp_v, 1, 1, total);
  const double one = 1.0;
  for (std::size_t i = 0; i < total; ++i) {
    const double log_gain = std::log(tau[i] / act[i]);  // Eq. 4.39
    design.AddRow(angle[i], vel[i], std::span(&one, 1), std::span(&log_gain, 1));
  }
  ReducedLeastSquares system = design.Reduced(0, bends);
  if (bends > 0) {
    const double w = std::sqrt(options.smoothness * static_cast<double>(total));
    Eigen::Index row = system.a.rows() - bends;
    for (const auto& [first, count] : {std::pair{Eigen::Index{0}, ma}, std::pair{ma, mv}}) {
      for (Eigen::Index j = 1; j + 1 < count; ++j, ++row) {
        system.a(row, first + j - 1) = w;
        system.a(row, first + j) = -2.0 * w;
        system.a(row, first + j + 1) = w;
      }
    }
  }
  const LeastSquaresSolution sol = SolveTruncatedSvd(std::move(system), options.relative_tolerance);
  std::vector<double> fata(static_cast<std::size_t>(ma)), fatv(static_cast<std::size_t>(mv));
  for (Eigen::Index j = 0; j < ma; ++j) fata[static_cast<std::size_t>(j)] = std::exp(sol.c(j));
  for (Eigen::Index j = 0; j < mv; ++j) fatv[static_cast<std::size_t>(j)] = std::exp(sol.c(ma + j));
  ActiveParams raw;
  raw.torque_scale_nm = std::exp(sol.c(ma + mv));
  raw.torque_angle = PiecewiseLinear(bp_a, std::move(fata));
  raw.torque_velocity = PiecewiseLinear(bp_v, std::move(fatv));
  ActiveResult res;
  res.active = NormaliseActive(raw);  // §6.7
  double ss = 0.0;
  std::size_t segment_a = 0, segment_v = 0;
  for (std::size_t i = 0; i < total; ++i) {
    const double pred = res.active.torque_scale_nm * act[i] *
                        res.active.torque_angle(angle[i], segment_a) *
                        res.active.torque_velocity(vel[i], segment_v);
    ss += (pred - tau[i]) * (pred - tau[i]);
  }
  res.report.fit_rms["active_log"] =
      std::sqrt(design.ResidualSquared(sol.c, 0) / static_cast<double>(total));
  res.report.fit_rms["active_nm"] = std::sqrt(ss / static_cast<double>(total));
  res.report.values["active_rank"] = sol.rank;
  res.report.values["active_parameters"] = static_cast<double>(ma + mv + 1);
  res.report.values["active_samples"] = static_cast<double>(total);
  res.report.values["active_skipped_nonpositive"] = static_cast<double>(skipped_nonpositive);
  // Two null directions are inherent (log τ_scale against each curve's level).
  if (sol.rank < ma + mv - 1) {
    res.report.warnings.push_back("active: rank " + std::to_string(sol.rank) + " of " +
                                  std::to_string(ma + mv + 1) +
                                  " parameters (under-determined; shortest solution used)");
  }
  if (skipped_nonpositive > total / 20) {
    res.report.warnings.push_back("active: " + std::to_string(skipped_nonpositive) +
                                  " stimulated samples with non-positive active torque skipped "
                                  "(passive set inconsistent with the trial?)");
  }
  for (auto& w :
       SupportWarnings("f_ata", "deg", bp_a, BreakpointSupport(bp_a, angle), options.min_support))
    res.report.warnings.push_back(std::move(w));
  for (auto& w :
       SupportWarnings("f_atv", "deg/s", bp_v, BreakpointSupport(bp_v, vel), options.min_support))
    res.report.warnings.push_back(std::move(w));
  const Coverage cov = PhasePlaneCoverage(angle, vel, bp_a, bp_v);
  res.report.values["coverage"] = cov.share;
  if (auto w = CoverageWarning("active", cov, options.coverage_warn_below); !w.empty()) {
    res.report.warnings.push_back(std::move(w));
  }
  return res;
}

}  // namespace fesbench::model
