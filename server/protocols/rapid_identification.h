#pragma once

/// @file
/// The identification rapid_parameterisation ends with (§7.4.1): picks the
/// three recorded trials, the known inertia (SubjectContext::inertia_kgm2,
/// else the prior parameter set's, else Eq. 4.13 from body mass and leg
/// length) and runs model::IdentifyRapid.

#include <optional>
#include <string>
#include <vector>

#include "api/status.h"
#include "model/parameter_set.h"
#include "model/simulate.h"
#include "server/protocols/plan.h"

namespace fesbench::server::protocols {

struct RecordedTrial;

/// The inertia the rapid fit uses, kg·m²; kInvalidArgument (field
/// "parameters.inertia_kgm2", saying how to provide one) if none of the
/// sources is available.
api::Result<double> KnownInertia(const SubjectContext& subject);

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

}  // namespace fesbench::server::protocols
