#include "server/protocols/daily_check_protocol.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "api/model_call.h"
#include "api/trial.h"
#include "model/daily_check.h"
#include "server/protocols/model_gate.h"
#include "server/protocols/runner.h"

namespace fesbench::server::protocols {
namespace {

// E_RMS (Eq. 6.9) of `params` predicting the recorded free swing from its
// measured start, with the pulses the stimulator delivered.
double SwingErms(const model::ParameterSet& params, const api::Trial& trial,
                 const model::JointLimits& stops) {
  const std::vector<double>* angle = trial.Values("angle_deg");
  if (angle == nullptr || angle->size() < 2 || !trial.pulses) return std::nan("");
  model::SimulationOptions o;
  o.initial_angle_deg = std::clamp(angle->front(), stops.min_angle_deg, stops.max_angle_deg);
  o.duration_s = static_cast<double>(angle->size() - 1) / trial.sample_rate_hz;
  o.output_rate_hz = trial.sample_rate_hz;
  o.pulse_rate_hz = trial.pulses->pulse_rate_hz;
  o.joint_limits = stops;
  // A swing the model cannot simulate has no E_RMS.
  const api::Result<model::SimulationResult> sim =
      api::CallModel([&] { return SimulateStimulatedSwing(params, trial.pulses->Train(), o); });
  if (!sim.ok()) return std::nan("");
  const std::size_t n = std::min(sim->angle_deg.size(), angle->size());
  double sum = 0.0;
  for (std::size_t i = 0; i < n; ++i) sum += std::pow(sim->angle_deg[i] - (*angle)[i], 2);
  return n ? std::sqrt(sum / static_cast<double>(n)) : std::nan("");
}

nlohmann::json Finite(double v) { return std::isfinite(v) ? nlohmann::json(v) : nullptr; }

}  // namespace

api::Result<DailyCheckOutcome> EvaluateDailyCheck(const DailyCheckSettings& settings,
                                                  const std::vector<RecordedTrial>& trials,
                                                  const SubjectContext& subject,
                                                  const model::JointLimits& stops) {
  if (!subject.parameter_set) {
    return api::Status::FailedPrecondition(NoApprovedSetMessage("daily_check"));
  }
  const auto trial = [&](int index) -> const api::Trial* {
    if (index < 0 || static_cast<std::size_t>(index) >= trials.size()) return nullptr;
    return &trials[static_cast<std::size_t>(index)].trial;
  };
  const api::Trial* ramp = trial(settings.ramp_trial);
  const api::Trial* swing = trial(settings.swing_trial);
  if (ramp == nullptr || swing == nullptr) {
    return api::Status::FailedPrecondition("daily_check: a trial is missing");
  }
  api::Result<model::DailyCheck> compared = api::CallModel([&] {
    return model::CompareDaily(*subject.parameter_set, api::ToTrialColumns(*ramp),
                               settings.lock_angle_deg, subject.history,
                               subject.base_ramp_trial ? &*subject.base_ramp_trial : nullptr);
  });
  if (!compared.ok()) {
    return api::Status::FailedPrecondition("daily_check: today's ramp trial: " +
                                           compared.status().message());
  }
  model::DailyCheck check = *std::move(compared);
  const double stored_erms = SwingErms(*subject.parameter_set, *swing, stops);
  const double updated_erms =
      check.updated ? SwingErms(*check.updated, *swing, stops) : std::nan("");
  if (check.updated && !(updated_erms <= stored_erms + 1.0)) {
    // The re-fit does not predict today's swing: more than the ramp moved.
    check.verdict = model::DailyVerdict::kRapidDue;
    check.summary += "; but the re-fitted set predicts today's free swing worse (E_RMS " +
                     std::to_string(updated_erms) + "° vs " + std::to_string(stored_erms) +
                     "°): a full rapid_parameterisation run is due";
    check.updated.reset();
  }
  DailyCheckOutcome out;
  nlohmann::json drifts = nlohmann::json::array();
  for (const model::Drift& d : check.drifts) {
    drifts.push_back({{"name", d.name},
                      {"stored", d.stored},
                      {"today", d.today},
                      {"change", d.change},
                      {"bound", d.bound},
                      {"moved", d.moved}});
  }
  out.report = {{"verdict", std::string(model::DailyVerdictName(check.verdict))},
                {"summary", check.summary},
                {"drifts", std::move(drifts)},
                {"refitted", check.updated ? check.refitted : std::vector<std::string>{}},
                {"recruitment_misfit", Finite(check.recruitment_misfit)},
                {"history_sets", subject.history.size()},
                {"compared_with", subject.base_ramp_trial ? "the set's own ramp trial"
                                                           : "the set's model"},
                {"base_parameter_set_id", subject.parameter_set_id
                                              ? nlohmann::json(*subject.parameter_set_id)
                                              : nlohmann::json(nullptr)},
                {"swing_e_rms_deg", {{"stored", Finite(stored_erms)},
                                     {"updated", Finite(updated_erms)}}}};
  out.updated = std::move(check.updated);
  return out;
}

api::Status DailyCheckEvaluation::Analyse(const std::vector<RecordedTrial>& trials,
                                          const SubjectContext& subject,
                                          const model::JointLimits& stops,
                                          RunResult& result) const {
  api::Result<DailyCheckOutcome> check = EvaluateDailyCheck(settings_, trials, subject, stops);
  if (!check.ok()) return check.status();
  result.daily_check = std::move(check->report);
  if (check->updated) result.parameter_set = std::move(check->updated);
  return api::Status::Ok();
}

}  // namespace fesbench::server::protocols
