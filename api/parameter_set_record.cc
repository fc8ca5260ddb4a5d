#include "api/parameter_set_record.h"

#include <utility>

#include "api/json_fields.h"
#include "api/json_read.h"
#include "api/parameter_set_json.h"
#include "api/time_utc.h"

namespace fesbench::api {
namespace {

using nlohmann::json;

Result<Approval> ApprovalFromJson(const json& j) {
  JsonFields in(j);
  Approval a;
  ReadInto(in, "approved_by", a.approved_by);
  ReadInto(in, "approved_by_user_id", a.approved_by_user_id);
  ReadTime(in, "approved_at_utc", false, a.approved_at);
  ReadInto(in, "note", a.note);
  ReadInto(in, "run_id", a.run_id);
  return ReadResult(in, std::move(a));
}

}  // namespace

json ApprovalStateToJson(const ApprovalState& state) {
  if (!state.newest) return {{"approved", state.approved}, {"approval", nullptr}};
  const Approval& a = *state.newest;
  return {{"approved", state.approved},
          {"approval",
           {{"approved_by", a.approved_by},
            {"approved_by_user_id", OrNull(a.approved_by_user_id)},
            {"approved_at_utc", FormatUtc(a.approved_at)},
            {"note", a.note},
            {"run_id", OrNull(a.run_id)}}}};
}

Result<ApprovalState> ApprovalStateFromJson(const json& j) {
  JsonFields in(j);
  ApprovalState state;
  ReadInto(in, "approved", state.approved);
  ReadNested(in, "approval", false, state.newest, &ApprovalFromJson);
  return ReadResult(in, std::move(state));
}

json ParameterSetSummaryToJson(const ParameterSetSummary& s) {
  json j = {{"id", s.id},
            {"subject_id", s.subject_id},
            {"leg_id", s.leg_id},
            {"version", s.version},
            {"model", s.model},
            {"irc_method", s.irc_method},
            {"passive_method", s.passive_method},
            {"active_method", s.active_method},
            {"software_version", s.software_version},
            {"supersedes_id", OrNull(s.supersedes_id)},
            {"created_at_utc", FormatUtc(s.created_at)}};
  if (s.approval) j.update(ApprovalStateToJson(*s.approval));
  return j;
}

Result<ParameterSetSummary> ParameterSetSummaryFromJson(const json& j) {
  JsonFields in(j);
  ParameterSetSummary s;
  s.id = in.Integer("id", true).value_or(0);
  ReadInto(in, "subject_id", s.subject_id);
  ReadInto(in, "leg_id", s.leg_id);
  ReadInto(in, "version", s.version);
  ReadInto(in, "model", s.model);
  ReadInto(in, "irc_method", s.irc_method);
  ReadInto(in, "passive_method", s.passive_method);
  ReadInto(in, "active_method", s.active_method);
  ReadInto(in, "software_version", s.software_version);
  ReadInto(in, "supersedes_id", s.supersedes_id);
  ReadTime(in, "created_at_utc", false, s.created_at);
  if (in.Any("approved", false) != nullptr) {
    Result<ApprovalState> approval = ApprovalStateFromJson(j);
    if (!approval.ok()) return approval.status();
    s.approval = *std::move(approval);
  }
  return ReadResult(in, std::move(s));
}

json StoredParameterSetToJson(const StoredParameterSet& set) {
  json j = ParameterSetSummaryToJson(set.summary);
  j["trial_ids"] = set.trial_ids;
  if (set.parameters) j["parameters"] = ParameterSetToJson(*set.parameters);
  j["fit_notes"] = set.fit_notes;
  return j;
}

Result<StoredParameterSet> StoredParameterSetFromJson(const json& j) {
  Result<ParameterSetSummary> summary = ParameterSetSummaryFromJson(j);
  if (!summary.ok()) return summary.status();
  JsonFields in(j);
  StoredParameterSet set;
  set.summary = *std::move(summary);
  ReadInto(in, "trial_ids", set.trial_ids);
  ReadNested(in, "parameters", false, set.parameters, &ParameterSetFromJson);
  ReadInto(in, "fit_notes", set.fit_notes);
  return ReadResult(in, std::move(set));
}

}  // namespace fesbench::api
