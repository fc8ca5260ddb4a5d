#include "server/services/identification_service.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <nlohmann/json.hpp>
#include <set>
#include <span>
#include <stdexcept>
#include <utility>

#include "api/model_call.h"
#include "api/trial_kind.h"
#include "model/conditioning.h"
#include "model/contraction.h"
#include "model/identify_active.h"
#include "model/identify_isometric.h"
#include "model/identify_passive.h"
#include "model/identify_passive_only.h"
#include "model/identify_rapid.h"
#include "model/identify_simplified.h"
#include "model/parameter_set.h"
#include "model/quality.h"
#include "server/services/stored_trials.h"
#include "storage/audit_log.h"
#include "storage/parameter_sets.h"
#include "storage/sessions.h"
#include "storage/subjects.h"
#include "storage/trials.h"

namespace fesbench::server::services {
namespace {

using model::TrialColumns;

// The kind a stored trial is fitted as (api/trial_kind.h, stored with the
// trial): every kind but the tolerance test and the validation trials.
using api::TrialKind;

std::optional<TrialKind> FittedKind(std::optional<TrialKind> kind) {
  if (!kind || *kind == TrialKind::kToleranceTest || api::IsValidation(*kind)) return std::nullopt;
  return kind;
}

// The trials of one leg, sorted by kind (ids ascending within a kind).
struct Selection {
  std::int64_t subject_id = 0;
  std::int64_t leg_id = 0;
  std::map<TrialKind, std::vector<LoadedTrial>> by_kind;
  std::set<std::int64_t> imported;  // free swings and pendulum tests recorded elsewhere
  std::vector<std::string> warnings;

  const std::vector<LoadedTrial>& Of(TrialKind kind) const {
    static const std::vector<LoadedTrial> kNone;
    const auto it = by_kind.find(kind);
    return it == by_kind.end() ? kNone : it->second;
  }
  const LoadedTrial* Latest(TrialKind kind) const {
    const auto& v = Of(kind);
    return v.empty() ? nullptr : &v.back();
  }
};

// Everything the fit needs besides the trials.
struct FitContext {
  std::optional<double> body_mass_kg;
  std::optional<double> leg_length_m;
  std::optional<model::ParameterSet> torque_angle_source;  // free swing τ_pta
  std::optional<std::int64_t> torque_angle_source_id;
  std::optional<model::ParameterSet> latest;  // the leg's latest set (rapid inertia)
  // The recorded threshold of the session of the rapid isometric ramp: the
  // IRC's onset (model::RapidOptions::threshold_ma).
  std::optional<double> rapid_threshold_ma;
};

struct ModelFit {
  model::ParameterSet params;
  model::IdentifyReport report;  // its own part (active or variant)
};

struct FitOutcome {
  std::vector<ModelFit> fits;      // request.models order
  model::IdentifyReport common;    // conditioning, contraction, IRC, passive
  std::vector<std::int64_t> used;  // trial ids
};

std::string Missing(std::string_view what, std::string_view names) {
  return std::string(what) + " needs " + std::string(names) + "; the selected trials have none";
}

class Fitter {
 public:
  Fitter(const IdentificationRequest& request, const IdentificationConfig& config,
         const Selection& selection, const FitContext& context)
      : req_(request),
        config_(config),
        sel_(selection),
        ctx_(context),
        passive_(request.passive_method) {}

  // What the model refuses in the stored trials is a failed precondition
  // of the fit, named by the stage it stopped in (docs/ARCHITECTURE.md, Errors).
  api::Result<FitOutcome> Run() {
    api::Result<api::Result<FitOutcome>> fitted =
        api::CallModel([&] { return Method(); }, {}, api::ErrorCode::kFailedPrecondition);
    if (!fitted.ok()) {
      return api::Status(fitted.status().code(),
                         "identification (" + stage_ + "): " + fitted.status().message());
    }
    return std::move(fitted).value();
  }

 private:
  api::Result<FitOutcome> Method() {
    switch (req_.method) {
      case model::IdentificationMethod::kRapid:
        return Rapid();
      case model::IdentificationMethod::kPassive:
        return PassiveOnly();
      case model::IdentificationMethod::kThesis:
        break;
    }
    return Thesis();
  }

  TrialColumns Columns(const LoadedTrial& t) {
    used_.insert(t.id);
    TrialColumns c = api::ToTrialColumns(t.trial);
    if (const api::ChannelGroup* emg = t.trial.emg ? &*t.trial.emg : nullptr) {
      if (const std::vector<double>* v = emg->Values("emg_mv"); v != nullptr) {
        // Refused (too short a recording to compare): nothing to report.
        const api::Result<model::EmgComparison> cmp =
            api::CallModel([&] { return model::CompareEmgPrePost(*v, emg->sample_rate_hz); });
        if (cmp.ok() && cmp->voluntary_contraction) {
          common_.warnings.push_back(
              "trial " + std::to_string(t.id) + ": EMG differs before and after (ratio " +
              std::to_string(cmp->ratio) + "): voluntary contraction? (§5.2.1)");
        }
      }
    }
    return c;
  }

  // §5.1: θ̇ and θ̈ from θ by the GCV smoothing spline when not recorded.
  void EnsureKinematics(TrialColumns& c) {
    if (c.velocity_deg_s.size() == c.size() && c.accel_deg_s2.size() == c.size()) return;
    model::AddKinematics(c);
    common_.values["gcv_derived_trials"] += 1.0;
  }

  void EnsureActivation(TrialColumns& c, const model::ParameterSet& p) {
    if (c.activation.size() == c.size() && !c.activation.empty()) return;
    const model::PulseTrain pulses = model::TrialPulses(c, config_.pulse_rate_hz);
    std::vector<double> rel(c.t_s);
    for (double& t : rel) t -= c.t_s.front();
    c.activation = model::ActivationAt(p.contraction, p.irc, pulses, config_.pulse_rate_hz, rel);
  }

  std::vector<TrialColumns> ColumnsOfAll(TrialKind kind) {
    std::vector<TrialColumns> out;
    for (const LoadedTrial& t : sel_.Of(kind)) out.push_back(Columns(t));
    return out;
  }

  // What the selected trials lack, by the blocks of the model they fit.
  struct MissingTrials {
    std::vector<std::string> stimulated;  // IRC and contraction dynamics
    std::vector<std::string> passive;
    std::vector<std::string> active;
  };

  MissingTrials CheckPresent() const {
    const auto has = [&](TrialKind k) { return !sel_.Of(k).empty(); };
    const model::IrcMethod irc = req_.irc_method;
    MissingTrials missing;
    if (irc == model::IrcMethod::kStep && !has(TrialKind::kStepIrc)) {
      missing.stimulated.push_back(Missing("irc_method step", "an isometric_step_irc trial"));
    } else if (irc == model::IrcMethod::kImpulse && !has(TrialKind::kImpulseIrc)) {
      missing.stimulated.push_back(
          Missing("irc_method impulse", "an isometric_impulse_irc trial"));
    } else if (irc != model::IrcMethod::kStep && irc != model::IrcMethod::kImpulse &&
               !has(TrialKind::kRampIrc)) {
      missing.stimulated.push_back(Missing("irc_method " + std::string(model::IrcMethodName(irc)),
                                           "an isometric_ramp_irc trial"));
    }
    if (!has(TrialKind::kRampIrc) && !has(TrialKind::kImpulseIrc)) {
      missing.stimulated.push_back(
          Missing("the contraction dynamics (single-pulse responses)",
                  "an isometric_ramp_irc or isometric_impulse_irc trial"));
    }
    if (passive_ == model::PassiveMethod::kSequential &&
        (!has(TrialKind::kPassivePositions) || !has(TrialKind::kPassiveVelocities))) {
      missing.passive.push_back(Missing("passive_method sequential",
                                        "a passive_positions and a passive_velocities trial"));
    }
    if (passive_ == model::PassiveMethod::kSimultaneous && !has(TrialKind::kPassiveSimultaneous)) {
      missing.passive.push_back(
          Missing("passive_method simultaneous", "passive_simultaneous_* trials"));
    }
    if (passive_ == model::PassiveMethod::kFreeSwing) {
      if (!has(TrialKind::kFreeSwingPassive)) {
        missing.passive.push_back(
            Missing("passive_method free_swing", "a free_swing_passive trial"));
      }
      if (!has(TrialKind::kPassivePositions) && !ctx_.torque_angle_source) {
        missing.passive.push_back(
            "passive_method free_swing needs τ_pta (Eq. 4.35): a passive_positions trial or a "
            "stored parameter set of the leg (torque_angle_parameter_set_id)");
      }
      // Its swings are stimulated (§5.4.3): their passive samples are known
      // only through the IRC and the contraction dynamics.
      for (const std::string& m : missing.stimulated) {
        missing.passive.push_back("passive_method free_swing (its stimulated swings) needs " + m);
      }
    }
    if (!has(TrialKind::kActive)) {
      missing.active.push_back(Missing("the active fit", "active_random_binary_* trials"));
    }
    return missing;
  }

  api::Status Refusal(const MissingTrials& missing) const {
    std::vector<std::string> all = missing.stimulated;
    all.insert(all.end(), missing.passive.begin(), missing.passive.end());
    all.insert(all.end(), missing.active.begin(), missing.active.end());
    std::string msg = "missing trials: ";
    for (std::size_t i = 0; i < all.size(); ++i) msg += (i ? "; " : "") + all[i];
    msg += PassiveHint();
    return api::Status::FailedPrecondition(msg);
  }

  // What free swings without stimulation support when a method needs more.
  std::string PassiveHint() const {
    return sel_.Of(TrialKind::kFreeSwingPassive).empty() && sel_.Of(TrialKind::kPendulum).empty()
               ? ""
               : " (the unstimulated swings alone support method passive: the passive curves "
                 "without the stimulated muscle)";
  }

  std::string PassiveName() const { return std::string(model::PassiveMethodName(passive_)); }

  std::optional<double> Inertia() const {
    if (req_.inertia_kgm2) return req_.inertia_kgm2;
    if (ctx_.body_mass_kg && ctx_.leg_length_m) {
      return model::AnthropometricInertia(*ctx_.body_mass_kg, *ctx_.leg_length_m);  // Eq. 4.13
    }
    return std::nullopt;
  }

  // The chapter 4 methods. Trials that support the passive block but not
  // the stimulated ones give a passive-only set (model::IsPassiveOnly) with
  // what was not fitted named; without the passive block nothing is fitted.
  api::Result<FitOutcome> Thesis() {
    const MissingTrials missing = CheckPresent();
    if (!missing.passive.empty()) return Refusal(missing);
    const bool with_irc = missing.stimulated.empty();
    const bool with_active = with_irc && missing.active.empty();
    if (!with_active && req_.models != std::vector<model::ModelKind>{model::ModelKind::kFull}) {
      return Refusal(missing);  // the variants differ in their active curves
    }
    // The blocks not fitted keep the example set's values as placeholders.
    model::ParameterSet est = with_active ? model::ParameterSet{} : model::ExampleParameterSet();
    est.provenance = {};
    if (!with_irc) return PassiveOnlyThesis(est, missing, /*fit_passive=*/true);
    const model::IrcMethod irc_method = req_.irc_method;
    const std::string irc_name(model::IrcMethodName(irc_method));

    // Contraction dynamics from the averaged impulse responses (§4.1, Eqs. 4.2, 4.4).
    stage_ = "contraction dynamics";
    std::vector<TrialColumns> twitch_trials = ColumnsOfAll(TrialKind::kRampIrc);
    for (TrialColumns& c : ColumnsOfAll(TrialKind::kImpulseIrc))
      twitch_trials.push_back(std::move(c));
    model::ContractionOptions co;
    co.order = req_.contraction_order;
    co.method = req_.pole_method;
    const model::ContractionResult contraction = model::IdentifyContraction(twitch_trials, co);
    est.contraction = contraction.contraction;
    common_.Merge(contraction.report);

    // IRC (§4.1) from the latest trial of the kind the method needs.
    stage_ = "IRC (" + irc_name + ")";
    const TrialKind irc_kind = irc_method == model::IrcMethod::kStep      ? TrialKind::kStepIrc
                               : irc_method == model::IrcMethod::kImpulse ? TrialKind::kImpulseIrc
                                                                          : TrialKind::kRampIrc;
    model::IrcOptions io;
    io.ideal.pole_per_s = 0.0;  // from the trial's impulses (Eqs. 4.2, 4.4)
    const model::IrcResult irc =
        model::IdentifyIrc(irc_method, Columns(*sel_.Latest(irc_kind)), io);
    est.irc = irc.irc;
    est.active.torque_scale_nm = irc.torque_scale_nm;
    est.provenance.irc_method = irc_name;
    common_.Merge(irc.report);

    // Passive (§4.2).
    stage_ = "passive (" + PassiveName() + ")";
    if (api::Status s = Passive(est); !s.ok()) return s;
    est.provenance.passive_method = PassiveName();
    if (!with_active) return PassiveOnlyThesis(est, missing, /*fit_passive=*/false);

    // Active and variants (§4.3, §5.5.1, §7.3, §7.4.4) on the active trials.
    stage_ = "active";
    std::vector<TrialColumns> active = ColumnsOfAll(TrialKind::kActive);
    for (TrialColumns& c : active) {
      EnsureKinematics(c);
      EnsureActivation(c, est);
    }
    est.provenance.active_trial_id = sel_.Of(TrialKind::kActive).front().id;
    return Variants(est, active);
  }

  // The set of a thesis fit without active trials (or without the IRC's):
  // the passive block fitted (and the IRC and contraction dynamics when
  // their trials are there), the rest named and marked "none".
  api::Result<FitOutcome> PassiveOnlyThesis(model::ParameterSet& est, const MissingTrials& missing,
                                            bool fit_passive) {
    if (fit_passive) {
      stage_ = "passive (" + PassiveName() + ")";
      if (api::Status s = Passive(est); !s.ok()) return s;
      est.provenance.passive_method = PassiveName();
    }
    std::string not_fitted;
    for (const std::string& m : missing.stimulated) not_fitted += "; " + m;
    for (const std::string& m : missing.active) not_fitted += "; " + m;
    model::MarkPassiveOnly(est, /*irc_identified=*/missing.stimulated.empty());
    common_.warnings.push_back(
        "passive only: not identified" + not_fitted.substr(1) +
        ". This set predicts swings without stimulation and cannot be approved to drive "
        "stimulation.");
    est.model = model::ModelKind::kFull;
    return OneFit({est, {}});
  }

  // The outcome of a fit that stores one set.
  FitOutcome OneFit(ModelFit fit) {
    FitOutcome out;
    out.fits.push_back(std::move(fit));
    out.common = common_;
    out.used.assign(used_.begin(), used_.end());
    return out;
  }

  api::Status Passive(model::ParameterSet& est) {
    const auto& bp = req_.breakpoints;
    if (passive_ == model::PassiveMethod::kSimultaneous) {
      std::vector<TrialColumns> motor = ColumnsOfAll(TrialKind::kPassiveSimultaneous);
      for (TrialColumns& c : motor) EnsureKinematics(c);
      model::SimultaneousPassiveOptions o;
      if (bp.passive_angle) o.angle = *bp.passive_angle;
      if (bp.passive_velocity) o.velocity = *bp.passive_velocity;
      const model::PassiveResult r = model::IdentifyPassiveSimultaneous(motor, o);  // Eq. 4.31
      est.passive = r.passive;
      common_.Merge(r.report);
      return api::Status::Ok();
    }
    std::optional<model::PassiveResult> sequential;
    if (sel_.Latest(TrialKind::kPassivePositions) && sel_.Latest(TrialKind::kPassiveVelocities) &&
        (passive_ == model::PassiveMethod::kSequential || passive_ == model::PassiveMethod::kFreeSwing)) {
      TrialColumns pos = Columns(*sel_.Latest(TrialKind::kPassivePositions));
      TrialColumns vel = Columns(*sel_.Latest(TrialKind::kPassiveVelocities));
      EnsureKinematics(pos);
      EnsureKinematics(vel);
      model::SequentialPassiveOptions o;
      const std::optional<double> inertia = Inertia();
      if (!inertia && passive_ == model::PassiveMethod::kSequential) {
        return api::Status::FailedPrecondition(
            "passive_method sequential needs the limb inertia: give inertia_kgm2 or record the "
            "subject's weight and shank length (Eq. 4.13)");
      }
      if (inertia) o.inertia_kgm2 = *inertia;
      sequential = model::IdentifyPassiveSequential(pos, vel, o);  // §4.2.1
    }
    if (passive_ == model::PassiveMethod::kSequential) {
      est.passive = sequential->passive;
      common_.Merge(sequential->report);
      return api::Status::Ok();
    }
    // free_swing (Eq. 4.35): τ_pta known.
    model::PiecewiseLinear torque_angle;
    if (sequential) {
      torque_angle = sequential->passive.torque_angle;
      common_.values["torque_angle_from_sequential"] = 1.0;
    } else if (const LoadedTrial* pos = sel_.Latest(TrialKind::kPassivePositions)) {
      TrialColumns c = Columns(*pos);
      const auto holds = model::DetectHolds(c.t_s, c.angle_deg, c.torque_nm, {});
      torque_angle = model::AverageHoldsByAngle(holds, /*acceleration=*/false);  // Eq. 4.10
    } else {
      torque_angle = ctx_.torque_angle_source->passive.torque_angle;
      common_.values["torque_angle_parameter_set_id"] =
          static_cast<double>(ctx_.torque_angle_source_id.value_or(0));
    }
    std::vector<TrialColumns> swing = ColumnsOfAll(TrialKind::kFreeSwingPassive);
    for (TrialColumns& c : swing) {
      EnsureKinematics(c);
      EnsureActivation(c, est);
    }
    model::FreeSwingPassiveOptions o;
    if (bp.passive_velocity) o.velocity = *bp.passive_velocity;
    const model::PassiveResult r = model::IdentifyPassiveFreeSwing(swing, torque_angle, o);
    est.passive = r.passive;
    common_.Merge(r.report);
    return api::Status::Ok();
  }

  api::Result<FitOutcome> Variants(const model::ParameterSet& base,
                                   const std::vector<TrialColumns>& active) {
    FitOutcome out;
    model::ActiveOptions ao;
    if (req_.breakpoints.active_angle) ao.angle = *req_.breakpoints.active_angle;
    if (req_.breakpoints.active_velocity) ao.velocity = *req_.breakpoints.active_velocity;
    for (const model::ModelKind kind : req_.models) {
      const std::string name(model::ModelKindName(kind));
      stage_ = "model " + name;
      ModelFit fit;
      if (kind == model::ModelKind::kFull) {
        const model::ActiveResult r = model::IdentifyActive(active, base.passive, ao);  // Eq. 4.40
        fit.params = base;
        fit.params.model = model::ModelKind::kFull;
        fit.params.active = r.active;
        fit.params.provenance.active_method = "log_least_squares";
        fit.report = r.report;
      } else {
        model::SimplifiedOptions so;
        so.active = ao;
        if (req_.breakpoints.active_velocity) so.velocity = *req_.breakpoints.active_velocity;
        const model::SimplifiedResult r = model::IdentifySimplified(kind, active, base, so);
        fit.params = r.params;
        fit.params.provenance = base.provenance;
        fit.params.provenance.active_method = name;
        fit.report = r.report;
      }
      out.fits.push_back(std::move(fit));
    }
    out.common = common_;
    out.used.assign(used_.begin(), used_.end());
    return out;
  }

  // Method passive (docs/MODEL.md "Passive-only identification"): τ_pta and
  // τ_ptv from unstimulated free swings (a pendulum test), with J given or
  // identified from the swings' period with gravity's moment fixed (given,
  // or from the anthropometrics). What it cannot fit is said in the set's
  // warnings.
  api::Result<FitOutcome> PassiveOnly() {
    std::vector<const LoadedTrial*> swings;
    for (TrialKind kind : {TrialKind::kPendulum, TrialKind::kFreeSwingPassive}) {
      for (const LoadedTrial& t : sel_.Of(kind)) swings.push_back(&t);
    }
    if (swings.empty()) {
      return api::Status::FailedPrecondition(
          "missing trials: method passive needs pendulum or free_swing_passive trials without "
          "stimulation; the selected trials have none");
    }
    std::optional<double> gravity = req_.gravity_moment_nm;
    if (!gravity && ctx_.body_mass_kg && ctx_.leg_length_m) {
      gravity = model::AnthropometricGravityMoment(*ctx_.body_mass_kg, *ctx_.leg_length_m);
    }
    if (!req_.inertia_kgm2 && !gravity) {
      return api::Status::FailedPrecondition(
          "method passive needs a torque scale (a free swing fixes the torques only relative to "
          "J): give gravity_moment_nm (m·g·l of shank and foot, then J is identified) or "
          "inertia_kgm2, or record the subject's weight and shank length");
    }
    std::vector<TrialColumns> trials;
    bool all_from_this_bench = true;
    for (const LoadedTrial* t : swings) {
      TrialColumns c = Columns(*t);
      if (c.stim_ma.empty()) c.stim_ma.assign(c.size(), 0.0);
      if (std::any_of(c.stim_ma.begin(), c.stim_ma.end(), [](double u) { return u != 0.0; })) {
        return api::Status::FailedPrecondition(
            "trial " + std::to_string(t->id) +
            " is stimulated; method passive uses unstimulated swings only (method thesis or "
            "rapid fits stimulated trials)");
      }
      if (sel_.imported.count(t->id)) all_from_this_bench = false;
      trials.push_back(std::move(c));
    }
    model::PassiveOnlyOptions o;
    if (req_.inertia_kgm2) o.inertia_kgm2 = *req_.inertia_kgm2;
    if (gravity) o.gravity_moment_nm = *gravity;
    // Swings that do not determine J (the tissue's mid-range stiffness
    // passing for gravity's) take Eq. 4.13's, when the body measures exist.
    if (ctx_.body_mass_kg && ctx_.leg_length_m) {
      o.fallback_inertia_kgm2 =
          model::AnthropometricInertia(*ctx_.body_mass_kg, *ctx_.leg_length_m);
    }
    if (req_.breakpoints.passive_angle) o.angle = *req_.breakpoints.passive_angle;
    if (req_.breakpoints.passive_velocity) o.velocity = *req_.breakpoints.passive_velocity;
    // Recordings from elsewhere swing without this bench's stops.
    if (all_from_this_bench) o.joint_limits = config_.joint_limits;
    stage_ = "passive only";
    const model::PassiveOnlyResult r = model::IdentifyPassiveOnly(trials, o);
    common_.values["inertia_kgm2"] = r.parameters.passive.inertia_kgm2;
    if (gravity) common_.values["gravity_moment_nm"] = *gravity;
    const bool j_identified = r.inertia_source == model::InertiaSource::kSwings;
    const std::string scale =
        req_.inertia_kgm2 ? "J given"
        : j_identified    ? "J identified from their period with m·g·l " +
                             std::string(req_.gravity_moment_nm ? "given" : "from the anthropometrics")
                          : "J from the anthropometrics (Eq. 4.13; the swings did not determine it)";
    common_.warnings.push_back(
        "passive only: τ_pta and τ_ptv fitted from " + std::to_string(trials.size()) +
        " unstimulated swing(s), " + scale +
        "; not identified: the contraction dynamics, the IRC and the active curves (no "
        "stimulated trial). This set predicts swings without stimulation and cannot be approved "
        "to drive stimulation.");
    ModelFit fit{r.parameters, r.report};
    fit.params.provenance.inertia_method =
        req_.inertia_kgm2        ? "given"
        : !j_identified          ? "anthropometric"
        : req_.gravity_moment_nm ? "pendulum_given_gravity"
                                 : "pendulum_anthropometric_gravity";
    return OneFit(std::move(fit));
  }

  api::Result<FitOutcome> Rapid() {
    const LoadedTrial* iso = sel_.Latest(TrialKind::kRapidRamp);
    const LoadedTrial* pas = sel_.Latest(TrialKind::kRapidPassive);
    const LoadedTrial* act = sel_.Latest(TrialKind::kRapidActive);
    std::vector<std::string> missing;
    if (!iso) missing.push_back("rapid_isometric_ramp_irc");
    if (!pas) missing.push_back("rapid_free_swing_passive");
    if (!act) missing.push_back("rapid_active_random_binary");
    if (!missing.empty()) {
      std::string names;
      for (std::size_t i = 0; i < missing.size(); ++i) names += (i ? ", " : "") + missing[i];
      return api::Status::FailedPrecondition(
          "missing trials: method rapid needs the trials of a rapid_parameterisation run; none "
          "named " +
          names + PassiveHint());
    }
    std::optional<double> inertia = Inertia();
    if (!inertia && ctx_.latest) inertia = ctx_.latest->passive.inertia_kgm2;
    if (!inertia) {
      return api::Status::FailedPrecondition(
          "method rapid needs the limb inertia (§7.4.1): give inertia_kgm2, record the subject's "
          "weight and shank length (Eq. 4.13), or store a parameter set of the leg first");
    }
    // Every trial of the rapid routine the run would use (plan.cc
    // BuildRapid): the releases, the extension search, the random-binary
    // trial, and the holds before the releases that measure J unless it is
    // given.
    model::RapidTrials trials;
    trials.isometric = Columns(*iso);
    trials.swings.push_back(Columns(*pas));
    const LoadedTrial* release = sel_.Latest(TrialKind::kRapidRelease);
    if (release) trials.swings.push_back(Columns(*release));
    if (const LoadedTrial* t = sel_.Latest(TrialKind::kRapidSearch)) {
      trials.swings.push_back(Columns(*t));
    }
    trials.swings.push_back(Columns(*act));
    const LoadedTrial* hold_flexion = sel_.Latest(TrialKind::kRapidHoldFlexion);
    const LoadedTrial* hold_extension = sel_.Latest(TrialKind::kRapidHoldExtension);
    if (!req_.inertia_kgm2 && hold_flexion && hold_extension && release) {
      trials.releases.push_back({Columns(*hold_flexion), 0});
      trials.releases.push_back({Columns(*hold_extension), 1});
    }
    model::RapidOptions o;
    o.inertia_kgm2 = *inertia;
    o.pulse_rate_hz = config_.pulse_rate_hz;
    o.joint_limits = config_.joint_limits;
    o.threshold_ma = ctx_.rapid_threshold_ma;
    if (ctx_.body_mass_kg && ctx_.leg_length_m) {
      o.mgl_prior_nm = model::AnthropometricGravityMoment(*ctx_.body_mass_kg, *ctx_.leg_length_m);
    }
    const auto& bp = req_.breakpoints;
    if (bp.passive_angle) o.passive_angle = *bp.passive_angle;
    if (bp.passive_velocity) o.passive_velocity = *bp.passive_velocity;
    if (bp.active_angle) o.active_angle = *bp.active_angle;
    if (bp.active_velocity) o.active_velocity = *bp.active_velocity;
    stage_ = "rapid parameterisation";
    TrialColumns active = Columns(*act);
    const model::RapidResult r = model::IdentifyRapid(trials, o);  // §7.4.1
    common_.values["inertia_kgm2"] = *inertia;
    model::ParameterSet base = r.parameters;
    if (base.provenance.inertia_method.empty()) {
      base.provenance.inertia_method = req_.inertia_kgm2                          ? "given"
                                       : (ctx_.body_mass_kg && ctx_.leg_length_m) ? "anthropometric"
                                                                                  : "prior_set";
    }
    base.provenance.active_trial_id = act->id;
    FitOutcome out;
    std::vector<TrialColumns> active_trials;
    for (const model::ModelKind kind : req_.models) {
      const std::string name(model::ModelKindName(kind));
      ModelFit fit;
      if (kind == model::ModelKind::kFull) {
        fit.params = base;
        fit.report = r.report;
      } else {
        if (active_trials.empty()) {
          model::AddKinematics(active);
          EnsureActivation(active, base);
          active_trials.push_back(active);
        }
        stage_ = "model " + name;
        model::SimplifiedOptions so;
        if (bp.active_angle) so.active.angle = *bp.active_angle;
        if (bp.active_velocity) so.active.velocity = so.velocity = *bp.active_velocity;
        const model::SimplifiedResult s = model::IdentifySimplified(kind, active_trials, base, so);
        fit.params = s.params;
        fit.params.provenance = base.provenance;
        fit.params.provenance.active_method = name;
        fit.report = r.report;
        fit.report.Merge(s.report);
      }
      out.fits.push_back(std::move(fit));
    }
    out.common = common_;
    out.used.assign(used_.begin(), used_.end());
    return out;
  }

  const IdentificationRequest& req_;
  const IdentificationConfig& config_;

  const Selection& sel_;
  const FitContext& ctx_;
  const model::PassiveMethod passive_;
  model::IdentifyReport common_;
  std::set<std::int64_t> used_;
  std::string stage_ = "conditioning";
};

api::Status CheckSpec(const std::optional<model::BreakpointSpec>& spec, const std::string& field) {
  if (!spec) return api::Status::Ok();
  if (spec->explicit_x.empty()) {
    if (spec->count < 2 || spec->count > 101) {
      return api::Status::InvalidArgument("breakpoint count must be 2–101", field);
    }
    return api::Status::Ok();
  }
  if (spec->explicit_x.size() < 2 || spec->explicit_x.size() > 101) {
    return api::Status::InvalidArgument("2–101 breakpoints", field);
  }
  for (std::size_t i = 0; i < spec->explicit_x.size(); ++i) {
    const double x = spec->explicit_x[i];
    if (!std::isfinite(x) || (i > 0 && !(x > spec->explicit_x[i - 1]))) {
      return api::Status::InvalidArgument("breakpoints must be finite and strictly increasing",
                                          field + "[" + std::to_string(i) + "]");
    }
  }
  return api::Status::Ok();
}

// Loads the selected trials and checks they are of one subject and leg.
api::Result<Selection> Select(storage::Database& db, const IdentificationRequest& req) {
  Selection sel;
  std::vector<std::int64_t> ids = req.trial_ids;
  bool explicit_ids = !ids.empty();
  if (req.session_id) {
    api::Result<std::vector<storage::TrialSummary>> list =
        storage::TrialRepository(db).ListForSession(*req.session_id);
    if (!list.ok()) return list.status();
    for (const storage::TrialSummary& t : *list) {
      if (FittedKind(t.kind)) ids.push_back(t.id);
    }
    if (ids.empty()) {
      // Still need the session's subject and leg for the message.
      return api::Status::FailedPrecondition("missing trials: session " +
                                             std::to_string(*req.session_id) +
                                             " has no trial of an identification protocol");
    }
  }
  std::sort(ids.begin(), ids.end());
  for (std::size_t i = 0; i < ids.size(); ++i) {
    api::Result<LoadedTrial> t = LoadTrial(db, ids[i]);
    if (!t.ok()) return t.status();
    const std::string field = "trial_ids[" + std::to_string(i) + "]";
    if (i == 0) {
      sel.subject_id = t->subject_id;
      sel.leg_id = t->leg_id;
    } else if (t->leg_id != sel.leg_id) {
      return api::Status::InvalidArgument(
          "trial " + std::to_string(t->id) + " is of another leg than trial " +
              std::to_string(ids.front()) + "; one fit uses one leg's trials",
          field);
    }
    const std::optional<TrialKind> kind = FittedKind(t->trial.kind);
    if (!kind) {
      if (explicit_ids) {
        return api::Status::InvalidArgument("trial " + std::to_string(t->id) + " (\"" +
                                                t->trial.name.value_or("") +
                                                "\") is not a trial of an identification protocol",
                                            field);
      }
      continue;
    }
    if (*kind == TrialKind::kFreeSwingPassive || *kind == TrialKind::kPendulum) {
      api::Result<std::optional<storage::TrialImport>> import =
          storage::TrialRepository(db).ImportOf(t->id);
      if (!import.ok()) return import.status();
      if (import->has_value()) sel.imported.insert(t->id);
    }
    sel.by_kind[*kind].push_back(std::move(t).value());
  }
  return sel;
}

nlohmann::json RequestSummary(const IdentificationRequest& req) {
  nlohmann::json models = nlohmann::json::array();
  for (model::ModelKind kind : req.models) models.push_back(model::ModelKindName(kind));
  nlohmann::json j = {{"method", model::IdentificationMethodName(req.method)},
                      {"irc_method", model::IrcMethodName(req.irc_method)},
                      {"passive_method", model::PassiveMethodName(req.passive_method)},
                      {"models", models}};
  if (req.session_id) j["session_id"] = *req.session_id;
  if (!req.trial_ids.empty()) j["trial_ids"] = req.trial_ids;
  return j;
}

}  // namespace

api::Status ValidateIdentificationRequest(const IdentificationRequest& req) {
  if (req.session_id.has_value() == !req.trial_ids.empty()) {
    return api::Status::InvalidArgument("give exactly one of session_id and trial_ids",
                                        req.session_id ? "trial_ids" : "session_id");
  }
  if (req.session_id && *req.session_id <= 0) {
    return api::Status::InvalidArgument("must be a positive id", "session_id");
  }
  std::set<std::int64_t> seen;
  for (std::size_t i = 0; i < req.trial_ids.size(); ++i) {
    const std::string field = "trial_ids[" + std::to_string(i) + "]";
    if (req.trial_ids[i] <= 0) return api::Status::InvalidArgument("must be a positive id", field);
    if (!seen.insert(req.trial_ids[i]).second) {
      return api::Status::InvalidArgument("duplicate trial id", field);
    }
  }
  if (req.trial_ids.size() > 100) {
    return api::Status::InvalidArgument("at most 100 trials", "trial_ids");
  }
  if (req.method == model::IdentificationMethod::kPassive &&
      req.models != std::vector<model::ModelKind>{model::ModelKind::kFull}) {
    return api::Status::InvalidArgument(
        "method passive fits the passive block of the full model only (the variants differ in "
        "their active curves)",
        "models");
  }
  if (req.contraction_order != 0 && req.contraction_order != 2 && req.contraction_order != 3) {
    return api::Status::InvalidArgument("must be 2, 3 or 0 (the better-fitting order)",
                                        "contraction_order");
  }
  if (req.models.empty()) return api::Status::InvalidArgument("name at least one model", "models");
  std::set<model::ModelKind> kinds;
  for (std::size_t i = 0; i < req.models.size(); ++i) {
    if (!kinds.insert(req.models[i]).second) {
      return api::Status::InvalidArgument("duplicate model", "models[" + std::to_string(i) + "]");
    }
  }
  const auto& bp = req.breakpoints;
  for (const auto& [spec, field] :
       {std::pair{&bp.passive_angle, "breakpoints.passive_angle"},
        std::pair{&bp.passive_velocity, "breakpoints.passive_velocity"},
        std::pair{&bp.active_angle, "breakpoints.active_angle"},
        std::pair{&bp.active_velocity, "breakpoints.active_velocity"}}) {
    if (api::Status s = CheckSpec(*spec, field); !s.ok()) return s;
  }
  if (req.inertia_kgm2 && !(std::isfinite(*req.inertia_kgm2) && *req.inertia_kgm2 > 0.01 &&
                            *req.inertia_kgm2 <= 10.0)) {
    return api::Status::InvalidArgument("must be in (0.01, 10] kg·m²", "inertia_kgm2");
  }
  if (req.gravity_moment_nm && !(std::isfinite(*req.gravity_moment_nm) &&
                                 *req.gravity_moment_nm > 0.1 && *req.gravity_moment_nm <= 100.0)) {
    return api::Status::InvalidArgument("must be in (0.1, 100] N·m", "gravity_moment_nm");
  }
  if (req.torque_angle_parameter_set_id && *req.torque_angle_parameter_set_id <= 0) {
    return api::Status::InvalidArgument("must be a positive id", "torque_angle_parameter_set_id");
  }
  return api::Status::Ok();
}

IdentificationService::IdentificationService(storage::Database& db, IdentificationConfig config)
    : db_(db), config_(config) {}

api::Result<IdentificationResult> IdentificationService::Fit(const Actor& actor,
                                                             const IdentificationRequest& request) {
  if (api::Status s = Require(actor, Permission::kAnalyse, "fitting parameter sets"); !s.ok()) {
    return s;
  }
  if (api::Status s = ValidateIdentificationRequest(request); !s.ok()) return s;
  try {
    api::Result<Selection> selection = Select(db_, request);
    if (!selection.ok()) return selection.status();

    FitContext ctx;
    api::Result<storage::Subject> subject =
        storage::SubjectRepository(db_).Get(selection->subject_id);
    if (!subject.ok()) return subject.status();
    const storage::SubjectDetails& d = subject->current.details;
    ctx.body_mass_kg = d.weight_kg;
    if (d.shank_length_cm) ctx.leg_length_m = *d.shank_length_cm / 100.0;
    storage::ParameterSetRepository sets(db_);
    // The prior a refit starts from is the leg's approved set, not its
    // newest row (docs/SAFETY.md): a candidate never feeds another fit.
    api::Result<storage::StoredParameterSet> latest = sets.Approved(selection->leg_id);
    if (latest.ok()) {
      ctx.latest = latest->params;
    } else if (latest.status().code() != api::ErrorCode::kNotFound) {
      return latest.status();
    }
    if (request.torque_angle_parameter_set_id) {
      api::Result<storage::StoredParameterSet> src =
          sets.Get(*request.torque_angle_parameter_set_id);
      if (!src.ok()) return src.status();
      if (src->summary.leg_id != selection->leg_id) {
        return api::Status::InvalidArgument("parameter set of another leg",
                                            "torque_angle_parameter_set_id");
      }
      ctx.torque_angle_source = src->params;
      ctx.torque_angle_source_id = src->summary.id;
    } else if (latest.ok()) {
      ctx.torque_angle_source = latest->params;
      ctx.torque_angle_source_id = latest->summary.id;
    }

    if (const LoadedTrial* ramp = selection->Latest(TrialKind::kRapidRamp)) {
      api::Result<storage::Session> session = storage::SessionRepository(db_).Get(ramp->session_id);
      if (!session.ok()) return session.status();
      const std::optional<double> threshold = session->current.details.threshold_ma;
      if (threshold && *threshold > 0.0) ctx.rapid_threshold_ma = threshold;
    }
    Fitter fitter(request, config_, *selection, ctx);
    api::Result<FitOutcome> outcome = fitter.Run();
    if (!outcome.ok()) return outcome.status();

    IdentificationResult result;
    result.subject_id = selection->subject_id;
    result.leg_id = selection->leg_id;
    result.trial_ids = outcome->used;
    result.report = outcome->common;
    for (const std::string& w : selection->warnings) result.report.warnings.push_back(w);
    for (const ModelFit& f : outcome->fits) result.report.Merge(f.report);

    const std::string software(storage::StorageSoftwareVersion());
    api::Status stored = db_.Write([&](storage::Connection&) -> api::Status {
      result.stored.clear();
      storage::ParameterSetRepository repo(db_);
      std::string targets;
      for (std::size_t i = 0; i < outcome->fits.size(); ++i) {
        const ModelFit& f = outcome->fits[i];
        storage::NewParameterSet set;
        set.subject_id = selection->subject_id;
        set.leg_id = selection->leg_id;
        set.params = f.params;
        model::Provenance& p = set.params.provenance;
        p.trial_ids = outcome->used;
        p.software_version = software;
        p.fit_rms.clear();
        p.warnings = outcome->common.warnings;
        for (const auto& [k, v] : outcome->common.fit_rms) p.fit_rms[k] = v;
        for (const auto& [k, v] : f.report.fit_rms) p.fit_rms[k] = v;
        for (const std::string& w : f.report.warnings) p.warnings.push_back(w);
        api::Result<storage::ParameterSetSummary> summary = repo.Insert(set);
        if (!summary.ok()) return summary.status();
        result.stored.push_back({summary->id, summary->version, summary->model});
        targets += (i ? "," : "") + std::string("parameter-sets/") + std::to_string(summary->id);
      }
      storage::NewAuditEntry entry;
      if (actor.user_id > 0) entry.user_id = actor.user_id;
      entry.actor = actor.user_name;
      entry.action = "identification.fit";
      entry.target = targets;
      entry.request_summary = RequestSummary(request).dump();
      entry.outcome = "ok";
      api::Result<std::int64_t> audit = storage::AuditLog(db_).Append(entry);
      if (!audit.ok()) return audit.status();
      result.audit_id = *audit;
      return api::Status::Ok();
    });
    if (!stored.ok()) return stored;
    return result;
  } catch (const std::exception& e) {
    return api::Status::Internal(std::string("identification: ") + e.what());
  }
}

}  // namespace fesbench::server::services
