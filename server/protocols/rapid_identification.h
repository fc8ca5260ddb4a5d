#pragma once

/// @file
/// The identification rapid_parameterisation ends with (§7.4.1): picks the
/// three recorded trials, the known inertia (SubjectContext::inertia_kgm2,
/// else the prior parameter set's, else Eq. 4.13 from body mass and leg
/// length) and runs model::IdentifyRapid; RapidIdentification is that
/// identification as the rapid plan's analysis (Plan::analysis).

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "api/status.h"
#include "model/parameter_set.h"
#include "model/simulate.h"
#include "server/protocols/plan.h"

namespace fesbench::server::protocols {

struct RecordedTrial;

/// The trials the rapid protocol's identification reads (indices into the
/// plan's trials).
struct RapidSettings {
  int ramp_trial = 0;
  int passive_trial = 1;  ///< the first released free swing.
  int active_trial = 2;
  /// Every free-swing trial besides active_trial (the released swings and
  /// the extension search), passive_trial first.
  std::vector<int> swing_trials;
  /// (recorded hold before a release, the free swing after it): they
  /// measure J (model::InertiaFromReleases).
  std::vector<std::pair<int, int>> release_trials;
};

/// The trials a set identified with `settings` is fitted to (ramp, the
/// holds before the releases, the free swings, the active trial), in
/// ascending order, each once.
std::vector<int> FittedTrials(const RapidSettings& settings);

/// The inertia the rapid fit uses, kg·m²; kInvalidArgument (field
/// "parameters.inertia_kgm2", saying how to provide one) if none of the
/// sources is available.
api::Result<double> KnownInertia(const SubjectContext& subject);

/// The explicit inertia among the protocol's `parameters`: inertia_kgm2
/// when it is > 0 (its 0 means "not given"), kg·m²; else unset.
std::optional<double> ExplicitInertia(const ParameterValues& parameters);

/// KnownInertia of `subject` with the explicit inertia (ExplicitInertia)
/// first.
api::Result<double> KnownInertia(const SubjectContext& subject, const ParameterValues& parameters);

/// Where KnownInertia's value comes from: "given" (an explicit
/// inertia_kgm2), "prior_set" (the leg's latest parameter set),
/// "anthropometric" (Eq. 4.13), or "" if none.
std::string InertiaSource(const SubjectContext& subject);

/// kFailedPrecondition without an inertia or when a trial is missing;
/// kFailedPrecondition naming the fit if identification fails. `stops` are
/// the bench's hard stops (samples in contact are left out of the fits and
/// the output-error simulations stop there); unset = the subject's range
/// of motion. The free swings are settings.swing_trials (else
/// passive_trial) and active_trial; with the subject's body mass and leg
/// length the gravity term of a short τ_pta range is m·g·l from them.
/// With settings.release_trials J is then measured by the releases
/// (model::InertiaFromReleases), unless it was given explicitly.
api::Result<model::ParameterSet> IdentifyRapidTrials(
    const std::vector<RecordedTrial>& trials, const RapidSettings& settings,
    const SubjectContext& subject, std::optional<model::JointLimits> stops = std::nullopt);

/// The identification the rapid protocol ends with, as its plan's
/// RunAnalysis (phase kIdentify): IdentifyRapidTrials with the explicit
/// inertia first, the bench's stops; the set goes to
/// RunResult::parameter_set, FittedTrials and active_trial to its
/// provenance fields. A failed fit fails the run with "identification
/// failed: " and the reason.
class RapidIdentification final : public RunAnalysis {
 public:
  /// `inertia_kgm2`: the explicit inertia (parameter inertia_kgm2 > 0), or
  /// unset.
  RapidIdentification(RapidSettings settings, std::optional<double> inertia_kgm2)
      : settings_(std::move(settings)), inertia_kgm2_(inertia_kgm2) {}

  const RapidSettings& settings() const { return settings_; }
  StepPhase phase() const override { return StepPhase::kIdentify; }
  api::Status Analyse(const std::vector<RecordedTrial>& trials, const SubjectContext& subject,
                      const model::JointLimits& stops, RunResult& result) const override;

 private:
  RapidSettings settings_;
  std::optional<double> inertia_kgm2_;
};

}  // namespace fesbench::server::protocols
