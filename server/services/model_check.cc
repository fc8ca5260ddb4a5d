#include "server/services/model_check.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <regex>
#include <set>

#include "api/trial_kind.h"
#include "storage/parameter_sets.h"
#include "storage/sessions.h"
#include "storage/trials.h"

namespace fesbench::server::services {
namespace {

std::string Fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

ModelVerdict Worse(ModelVerdict a, ModelVerdict b) {
  return static_cast<int>(a) >= static_cast<int>(b) ? a : b;
}

// The fresh validation trials of the set's leg, newest first.
api::Result<std::vector<storage::TrialSummary>> FreshTrials(
    storage::Database& db, const storage::StoredParameterSet& set) {
  auto sessions = storage::SessionRepository(db).ListForSubject(set.summary.subject_id);
  if (!sessions.ok()) return sessions.status();
  const std::set<std::int64_t> fitted(set.trial_ids.begin(), set.trial_ids.end());
  std::vector<storage::TrialSummary> out;
  storage::TrialRepository trials(db);
  for (const storage::Session& s : *sessions) {
    if (s.leg_id != set.summary.leg_id) continue;
    auto listed = trials.ListForSession(s.id);
    if (!listed.ok()) return listed.status();
    for (storage::TrialSummary& t : *listed) {
      if (!t.kind || !api::IsValidation(*t.kind) || fitted.contains(t.id)) continue;
      out.push_back(std::move(t));
    }
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.id > b.id; });
  if (out.size() > kModelCheckMaxTrials) out.resize(kModelCheckMaxTrials);
  return out;
}

// The range of a measured channel (max − min over finite samples), or unset.
std::optional<double> RangeOf(const std::vector<double>* values) {
  if (values == nullptr) return std::nullopt;
  double lo = INFINITY, hi = -INFINITY;
  for (double v : *values) {
    if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
  }
  if (!(hi > lo)) return std::nullopt;
  return hi - lo;
}

void Judge(const ModelCheckThresholds& th, ModelCheckTrial& t) {
  const double e = *t.e_rms;
  if (t.unit == "deg") {
    t.verdict = e <= th.angle_good_deg   ? ModelVerdict::kGoodForControl
                : e <= th.angle_care_deg ? ModelVerdict::kUseWithCare
                                         : ModelVerdict::kDoNotUse;
    t.explanation = "knee angle predicted within " + Fixed(e, 1) + "° RMS (good ≤ " +
                    Fixed(th.angle_good_deg, 1) + "°, with care ≤ " + Fixed(th.angle_care_deg, 1) +
                    "°)";
    if (t.share_outside && *t.share_outside > th.outside_care_share) {
      t.verdict = Worse(t.verdict, ModelVerdict::kUseWithCare);
      t.explanation += "; for " + Fixed(100.0 * *t.share_outside, 0) +
                       " % of the time the knee moved at angles or speeds the set was never "
                       "measured at, where the model guesses";
    }
    return;
  }
  if (!t.measured_range) {
    t.verdict = ModelVerdict::kDoNotUse;
    t.explanation = "the trial measured no torque to compare with";
    return;
  }
  const double share = e / *t.measured_range;
  t.verdict = share <= th.torque_good_share   ? ModelVerdict::kGoodForControl
              : share <= th.torque_care_share ? ModelVerdict::kUseWithCare
                                              : ModelVerdict::kDoNotUse;
  t.explanation = "torque predicted within " + Fixed(e, 1) + " N·m RMS, " +
                  Fixed(100.0 * share, 0) + " % of the " + Fixed(*t.measured_range, 1) +
                  " N·m the muscle produced (good ≤ " + Fixed(100.0 * th.torque_good_share, 0) +
                  " %, with care ≤ " + Fixed(100.0 * th.torque_care_share, 0) + " %)";
}

std::string Summary(const ModelCheck& c) {
  switch (c.verdict) {
    case ModelVerdict::kNoFreshTrials:
      return "No trial of this leg is left to check the set on: run a prediction protocol "
             "(e.g. prediction_random_binary) on the leg, then check again.";
    case ModelVerdict::kGoodForControl:
      return "The set predicted " +
             (c.trials.size() == 1 ? std::string("the one trial")
                                   : "all " + std::to_string(c.trials.size()) + " trials") +
             " it was not fitted on within the good thresholds.";
    case ModelVerdict::kUseWithCare:
      return "The set predicts the leg, but not everywhere within the good thresholds (see "
             "each trial); watch the first minutes of control closely.";
    case ModelVerdict::kDoNotUse:
      return "At least one trial it was not fitted on is predicted beyond the thresholds; run "
             "the rapid parameterisation again.";
  }
  return {};
}

}  // namespace

std::string ClinicalWarning(const std::string& w) {
  std::smatch m;
  static const std::regex skipped(R"(active: (\d+) stimulated samples with non-positive .*)");
  static const std::regex rank(R"((.*): rank \d+ of \d+ parameters.*)");
  static const std::regex support(R"((\w+): breakpoint ([-0-9.e+]+) (deg|deg/s) has support .*)");
  static const std::regex coverage(R"((.*): phase-plane coverage (\d+)% .*)");
  static const std::regex emg(R"(trial (\d+): EMG differs before and after.*)");
  if (w.find(" stimulated samples with non-positive") != std::string::npos &&
      std::regex_match(w, m, skipped)) {
    return "During stimulation the leg sometimes gave less torque than its passive model "
           "expects (" +
           m[1].str() +
           " samples); those moments were left out of the muscle fit. The subject may have "
           "moved or resisted, or the passive part of the set is off.";
  }
  if (w.find(": rank ") != std::string::npos && std::regex_match(w, m, rank)) {
    return "Some parts of the " + m[1].str() +
           " model could not be told apart from these recordings; the simplest values that "
           "explain them were used.";
  }
  if (w.find(": breakpoint ") != std::string::npos && std::regex_match(w, m, support)) {
    const bool speed = m[3].str() == "deg/s";
    return "The recordings hardly reach " + std::string(speed ? "the knee speed " : "the angle ") +
           m[2].str() + (speed ? " °/s" : "°") + ": there the " +
           (m[1].str().starts_with("tau_p") ? "passive" : "muscle") +
           " curve is a guess, not a measurement.";
  }
  if (w.find("phase-plane coverage") != std::string::npos &&
      std::regex_match(w, m, coverage)) {
    return "The " + m[1].str() + " recordings cover only " + m[2].str() +
           " % of the angle–speed combinations the model describes; outside them the model "
           "guesses.";
  }
  if (w.find(": EMG differs") != std::string::npos && std::regex_match(w, m, emg)) {
    return "In trial " + m[1].str() +
           " the muscle's electrical activity differed before and after stimulation: the "
           "subject may have tensed the leg.";
  }
  if (w.starts_with("J not measured") || w.starts_with("the releases give J")) {
    return "The leg's inertia could not be measured from the releases; the value entered was "
           "kept.";
  }
  if (w.find("inertia not positive") != std::string::npos) {
    return "The passive fit gave an impossible inertia: the passive part of this set is not "
           "reliable.";
  }
  if (w.starts_with("output-error refinement")) {
    return "The detailed fit did not improve the muscle curves; the first estimates were kept.";
  }
  return w;
}

api::Result<ModelCheck> CheckModel(storage::Database& db, PredictionService& predictions,
                                   const Actor& actor, std::int64_t parameter_set_id,
                                   const ModelCheckThresholds& thresholds) {
  auto set = storage::ParameterSetRepository(db).Get(parameter_set_id);
  if (!set.ok()) return set.status();
  auto fresh = FreshTrials(db, *set);
  if (!fresh.ok()) return fresh.status();

  ModelCheck check;
  check.parameter_set_id = parameter_set_id;
  check.thresholds = thresholds;
  for (const std::string& w : set->params.provenance.warnings) {
    check.technical_warnings.push_back(w);
    check.warnings.push_back(ClinicalWarning(w));
  }
  storage::TrialRepository trials(db);
  for (const storage::TrialSummary& summary : *fresh) {
    ModelCheckTrial t;
    t.trial_id = summary.id;
    t.trial_name = summary.name.value_or("");
    t.session_id = summary.session_id;
    PredictionRequest request;
    request.parameter_set_id = parameter_set_id;
    request.trial_id = summary.id;
    api::Result<PredictionResult> r = predictions.Predict(actor, request);
    if (!r.ok()) {
      if (r.status().code() == api::ErrorCode::kPermissionDenied) return r.status();
      t.verdict = ModelVerdict::kDoNotUse;
      t.explanation = "the set could not predict this trial: " + r.status().message();
      check.trials.push_back(std::move(t));
      continue;
    }
    t.prediction_id = r->prediction_id;
    if (r->errors) {
      t.unit = r->errors->unit;
      t.quantity = r->errors->channel == "torque_nm" ? "torque" : "knee angle";
      t.e_rms = r->errors->e_rms;
    }
    t.share_outside = r->share_outside_identified_ranges;
    if (t.unit != "deg") {
      auto trial = trials.Get(summary.id);
      if (!trial.ok()) return trial.status();
      t.measured_range = RangeOf(trial->Values("torque_nm"));
    }
    if (t.e_rms) {
      Judge(thresholds, t);
    } else {
      t.verdict = ModelVerdict::kDoNotUse;
      t.explanation = "the prediction has no error figures against the trial";
    }
    check.trials.push_back(std::move(t));
  }
  // The set's verdict is its worst trial's (none: nothing to judge on).
  if (!check.trials.empty()) {
    check.verdict = ModelVerdict::kGoodForControl;
    for (const ModelCheckTrial& t : check.trials) check.verdict = Worse(check.verdict, t.verdict);
  }
  check.summary = Summary(check);
  return check;
}

}  // namespace fesbench::server::services
