#pragma once

/// @file
/// The identification rapid_parameterisation ends with (§7.4.1): picks the
/// three recorded trials, the known inertia (SubjectContext::inertia_kgm2,
/// else the prior parameter set's, else Eq. 4.13 from body mass and leg
/// length) and runs model::IdentifyRapid.

#include <vector>

#include "api/status.h"
#include "model/parameter_set.h"
#include "server/protocols/plan.h"

namespace fesbench::server::protocols {

struct RecordedTrial;

/// The inertia the rapid fit uses, kg·m²; kInvalidArgument (field
/// "parameters.inertia_kgm2", saying how to provide one) if none of the
/// sources is available.
api::Result<double> KnownInertia(const SubjectContext& subject);

/// kFailedPrecondition without an inertia or when a trial is missing;
/// kFailedPrecondition naming the fit if identification fails.
api::Result<model::ParameterSet> IdentifyRapidTrials(const std::vector<RecordedTrial>& trials,
                                                     const RapidSettings& settings,
                                                     const SubjectContext& subject);

}  // namespace fesbench::server::protocols
