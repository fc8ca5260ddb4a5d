#include "server/protocols/rapid_identification.h"

#include <algorithm>
#include <stdexcept>

#include "api/model_call.h"
#include "model/identify_passive.h"
#include "model/identify_rapid.h"
#include "server/protocols/runner.h"

namespace fesbench::server::protocols {

api::Result<double> KnownInertia(const SubjectContext& subject) {
  if (subject.inertia_kgm2) return *subject.inertia_kgm2;
  if (subject.parameter_set && subject.parameter_set->passive.inertia_kgm2 > 0.0) {
    return subject.parameter_set->passive.inertia_kgm2;
  }
  if (subject.body_mass_kg && subject.leg_length_m) {
    api::Result<double> inertia = api::CallModel([&] {
      return model::AnthropometricInertia(*subject.body_mass_kg,
                                          *subject.leg_length_m);  // Eq. 4.13
    });
    if (!inertia.ok()) {
      return api::Status::FailedPrecondition("inertia from anthropometrics: " +
                                             inertia.status().message());
    }
    return inertia;
  }
  return api::Status::InvalidArgument(
      "rapid parameterisation needs the limb inertia: give it as parameters.inertia_kgm2 "
      "(kg·m², > 0), or record the subject's weight_kg and shank_length_cm (a correction: "
      "PATCH /api/v1/subjects/{id}, `fesbench subjects edit`) so that Eq. 4.13 gives it",
      "parameters.inertia_kgm2");
}

std::optional<double> ExplicitInertia(const ParameterValues& parameters) {
  const auto it = parameters.find("inertia_kgm2");
  if (it == parameters.end() || !(it->second > 0.0)) return std::nullopt;
  return it->second;
}

api::Result<double> KnownInertia(const SubjectContext& subject, const ParameterValues& parameters) {
  if (const std::optional<double> given = ExplicitInertia(parameters)) return *given;
  return KnownInertia(subject);
}

std::vector<int> FittedTrials(const RapidSettings& settings) {
  std::vector<int> fitted = {settings.ramp_trial, settings.passive_trial, settings.active_trial};
  fitted.insert(fitted.end(), settings.swing_trials.begin(), settings.swing_trials.end());
  for (const auto& [hold, swing] : settings.release_trials) fitted.push_back(hold);
  std::sort(fitted.begin(), fitted.end());
  fitted.erase(std::unique(fitted.begin(), fitted.end()), fitted.end());
  return fitted;
}

std::string InertiaSource(const SubjectContext& subject) {
  if (subject.inertia_kgm2) return "given";
  if (subject.parameter_set && subject.parameter_set->passive.inertia_kgm2 > 0.0) {
    return "prior_set";
  }
  if (subject.body_mass_kg && subject.leg_length_m) return "anthropometric";
  return "";
}

api::Result<model::ParameterSet> IdentifyRapidTrials(const std::vector<RecordedTrial>& trials,
                                                     const RapidSettings& settings,
                                                     const SubjectContext& subject,
                                                     std::optional<model::JointLimits> stops) {
  const api::Result<double> inertia = KnownInertia(subject);
  if (!inertia.ok()) return inertia.status();
  const auto pick = [&](int index) -> const RecordedTrial* {
    if (index < 0 || static_cast<std::size_t>(index) >= trials.size()) return nullptr;
    return &trials[static_cast<std::size_t>(index)];
  };
  const RecordedTrial* iso = pick(settings.ramp_trial);
  std::vector<int> swing_indices = settings.swing_trials;
  if (swing_indices.empty()) swing_indices.push_back(settings.passive_trial);
  swing_indices.push_back(settings.active_trial);
  model::RapidTrials rapid;
  for (int k : swing_indices) {
    const RecordedTrial* t = pick(k);
    if (t == nullptr)
      return api::Status::FailedPrecondition("rapid parameterisation: a trial is missing");
    rapid.swings.push_back(api::ToTrialColumns(t->trial));
  }
  if (iso == nullptr) {
    return api::Status::FailedPrecondition("rapid parameterisation: a trial is missing");
  }
  rapid.isometric = api::ToTrialColumns(iso->trial);
  const std::string source = InertiaSource(subject);
  // An explicit J is kept: the releases are not used to measure it.
  if (source != "given") {
    for (const auto& [hold, swing] : settings.release_trials) {
      const RecordedTrial* h = pick(hold);
      const auto at = std::find(swing_indices.begin(), swing_indices.end(), swing);
      if (h == nullptr || at == swing_indices.end()) continue;
      rapid.releases.push_back(
          {api::ToTrialColumns(h->trial), static_cast<std::size_t>(at - swing_indices.begin())});
    }
  }
  model::RapidOptions options;
  options.inertia_kgm2 = *inertia;
  if (subject.threshold_ma > 0.0) options.threshold_ma = subject.threshold_ma;
  options.joint_limits =
      stops.value_or(model::JointLimits{subject.min_angle_deg, subject.max_angle_deg});
  if (subject.body_mass_kg && subject.leg_length_m && *subject.body_mass_kg > 0.0 &&
      *subject.leg_length_m > 0.0) {
    options.mgl_prior_nm =
        model::AnthropometricGravityMoment(*subject.body_mass_kg, *subject.leg_length_m);
  }
  api::Result<model::RapidResult> r =
      api::CallModel([&] { return model::IdentifyRapid(rapid, options); }, {},
                     api::ErrorCode::kFailedPrecondition);
  if (!r.ok()) return r.status();
  model::ParameterSet& params = r->parameters;
  if (params.provenance.inertia_method.empty()) params.provenance.inertia_method = source;
  params.provenance.software_version = "fesbench 0.1.0";
  return params;
}

api::Status RapidIdentification::Analyse(const std::vector<RecordedTrial>& trials,
                                         const SubjectContext& subject,
                                         const model::JointLimits& stops,
                                         RunResult& result) const {
  SubjectContext with_inertia = subject;
  if (inertia_kgm2_) with_inertia.inertia_kgm2 = inertia_kgm2_;
  api::Result<model::ParameterSet> params =
      IdentifyRapidTrials(trials, settings_, with_inertia, stops);
  if (!params.ok()) {
    return api::Status(params.status().code(),
                       "identification failed: " + params.status().message());
  }
  result.parameter_set = std::move(params).value();
  result.parameter_set_trials = FittedTrials(settings_);
  result.parameter_set_active_trial = settings_.active_trial;
  return api::Status::Ok();
}

}  // namespace fesbench::server::protocols
