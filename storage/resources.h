#pragma once

/// @file
/// Stored rows as the api/ resources the server answers with
/// (docs/ARCHITECTURE.md, layering: storage maps its rows to the wire
/// types). Where a row and its resource are the same data storage uses the
/// api type itself (users, audit entries, trial summaries, details).

#include <optional>
#include <vector>

#include "api/parameter_set_record.h"
#include "api/session.h"
#include "api/subject.h"
#include "storage/parameter_sets.h"
#include "storage/sessions.h"
#include "storage/subjects.h"

namespace fesbench::storage {

api::Subject SubjectResource(const Subject& subject, const std::vector<Leg>& legs);
api::Session SessionResource(const Session& session, Side leg);

/// The revisions oldest first, each with the number of the revision it
/// corrects (ids → numbers).
std::vector<api::SubjectRevisionView> RevisionResources(
    const std::vector<SubjectRevision>& revisions);
std::vector<api::SessionRevisionView> RevisionResources(
    const std::vector<SessionRevision>& revisions);

/// The summary without its approval state (see ApprovalResource).
api::ParameterSetSummary ParameterSetResource(const ParameterSetSummary& summary);
/// The approval state a set's newest approval (none: never approved) says.
api::ApprovalState ApprovalResource(const std::optional<Approval>& newest);
/// The set with its parameters and provenance trials; no fit notes or
/// approval state (the server adds them).
api::StoredParameterSet StoredParameterSetResource(const StoredParameterSet& set);

}  // namespace fesbench::storage
