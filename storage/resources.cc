#include "storage/resources.h"

namespace fesbench::storage {
namespace {

template <typename Details, typename StoredRevision>
std::vector<api::Revision<Details>> Revisions(const std::vector<StoredRevision>& revisions) {
  std::vector<api::Revision<Details>> out;
  out.reserve(revisions.size());
  for (const StoredRevision& r : revisions) {
    api::Revision<Details> view;
    view.revision = r.revision;
    for (const StoredRevision& other : revisions) {
      if (r.corrects_id && other.id == *r.corrects_id) view.corrects_revision = other.revision;
    }
    view.reason = r.reason;
    if (!r.recorded_by.empty()) view.changed_by = r.recorded_by;
    view.changed_at = r.recorded_at;
    view.details = r.details;
    out.push_back(std::move(view));
  }
  return out;
}

}  // namespace

api::Subject SubjectResource(const Subject& subject, const std::vector<Leg>& legs) {
  api::Subject out;
  out.id = subject.id;
  out.code = subject.code;
  out.created_at = subject.created_at;
  out.revision = subject.current.revision;
  out.details = subject.current.details;
  for (const Leg& leg : legs) out.legs.push_back({leg.id, leg.side});
  return out;
}

api::Session SessionResource(const Session& session, Side leg) {
  api::Session out;
  out.id = session.id;
  out.subject_id = session.subject_id;
  out.leg_id = session.leg_id;
  out.leg = leg;
  out.created_at = session.created_at;
  out.revision = session.current.revision;
  out.details = session.current.details;
  return out;
}

std::vector<api::SubjectRevisionView> RevisionResources(
    const std::vector<SubjectRevision>& revisions) {
  return Revisions<SubjectDetails>(revisions);
}

std::vector<api::SessionRevisionView> RevisionResources(
    const std::vector<SessionRevision>& revisions) {
  return Revisions<SessionDetails>(revisions);
}

api::ParameterSetSummary ParameterSetResource(const ParameterSetSummary& s) {
  api::ParameterSetSummary out;
  out.id = s.id;
  out.subject_id = s.subject_id;
  out.leg_id = s.leg_id;
  out.version = s.version;
  out.model = s.model;
  out.irc_method = s.irc_method;
  out.passive_method = s.passive_method;
  out.active_method = s.active_method;
  out.software_version = s.software_version;
  out.supersedes_id = s.supersedes_id;
  out.created_at = s.created_at;
  return out;
}

api::ApprovalState ApprovalResource(const std::optional<Approval>& newest) {
  api::ApprovalState state;
  if (!newest) return state;
  state.approved = newest->current;
  state.newest = api::Approval{newest->approved_by, newest->approved_by_user_id,
                               newest->approved_at, newest->note, newest->run_id};
  return state;
}

api::StoredParameterSet StoredParameterSetResource(const StoredParameterSet& set) {
  api::StoredParameterSet out;
  out.summary = ParameterSetResource(set.summary);
  out.trial_ids = set.trial_ids;
  out.parameters = set.params;
  return out;
}

}  // namespace fesbench::storage
