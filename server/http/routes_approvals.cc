// A clinician's approval of a parameter set (docs/API.md, parameter-set
// approval; docs/SAFETY.md, which set gates stimulation): POST
// /parameter-sets/{id}/approve, and the approved set of a subject's leg.

#include <algorithm>

#include "api/json_fields.h"
#include "server/http/api_routes.h"
#include "server/http/resources_json.h"
#include "server/http/routes_common.h"
#include "storage/parameter_sets.h"
#include "storage/subjects.h"

namespace fesbench::server::http {
namespace {

using nlohmann::json;

constexpr std::size_t kMaxNoteLength = 500;

// {"note"}: why the clinician approves the set, printable text.
api::Result<std::string> ReadNote(const json& body) {
  api::JsonFields f(body);
  std::optional<std::string> note = f.String("note", true, kMaxNoteLength);
  if (api::Status s = f.Finish(); !s.ok()) return s;
  if (api::Status s = api::CheckPrintableText(*note, "note"); !s.ok()) return s;
  return *note;
}

// The set's resource with its approval state.
api::Result<json> ApprovedSetJson(storage::Database& db, const storage::StoredParameterSet& set) {
  auto approval = storage::ParameterSetRepository(db).LatestApprovals({set.summary.id});
  if (!approval.ok()) return approval.status();
  api::StoredParameterSet resource = ParameterSetResourceWithNotes(set);
  resource.summary.approval = storage::ApprovalResource(
      approval->empty() ? std::nullopt : std::optional(approval->front()));
  return api::StoredParameterSetToJson(resource);
}

api::Result<Reply> Approve(storage::Database& db, RequestContext& ctx) {
  const std::int64_t id = ctx.Id("parameter_set_id");
  auto note = ReadNote(ctx.body);
  if (!note.ok()) return note.status();
  storage::NewApproval approval;
  approval.parameter_set_id = id;
  approval.approved_by_user_id = ctx.user->id;
  approval.approved_by = ctx.user->name;
  approval.note = *note;
  auto approved = AuditedWrite<storage::Approval>(
      db, ctx, 200, [&] { return storage::ParameterSetRepository(db).Approve(approval); },
      [](const storage::Approval& a) {
        return "parameter-sets/" + std::to_string(a.parameter_set_id) + " (leg " +
               std::to_string(a.leg_id) + ")";
      });
  if (!approved.ok()) return approved.status();
  auto set = storage::ParameterSetRepository(db).Get(id);
  if (!set.ok()) return set.status();
  auto body = ApprovedSetJson(db, *set);
  if (!body.ok()) return body.status();
  return JsonReply(std::move(*body));
}

api::Result<Reply> LegApprovedSet(storage::Database& db, RequestContext& ctx) {
  const std::int64_t subject_id = ctx.Id("subject_id");
  const std::string side_name = ctx.path.at("leg");
  const std::optional<storage::Side> side = storage::ParseSide(side_name);
  if (!side) return api::Status::InvalidArgument("must be left or right", "leg");
  auto legs = storage::SubjectRepository(db).Legs(subject_id);
  if (!legs.ok()) return legs.status();
  const auto leg = std::find_if(legs->begin(), legs->end(),
                                [&](const storage::Leg& l) { return l.side == *side; });
  if (leg == legs->end()) {
    return api::Status::NotFound("subject " + std::to_string(subject_id) + " has no " + side_name +
                                 " leg");
  }
  auto set = storage::ParameterSetRepository(db).Approved(leg->id);
  if (!set.ok()) {
    if (set.status().code() != api::ErrorCode::kNotFound) return set.status();
    return api::Status::NotFound(
        "no parameter set is approved for subject " + std::to_string(subject_id) + "'s " +
        side_name +
        " leg: a clinician approves one (POST /api/v1/parameter-sets/{id}/approve with a note, "
        "or `fesbench params approve ID --note TEXT`), or runs rapid_parameterisation");
  }
  auto body = ApprovedSetJson(db, *set);
  if (!body.ok()) return body.status();
  return JsonReply(std::move(*body));
}

}  // namespace

void AddApprovalRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  table.Add({.method = "POST",
             .path = "/api/v1/parameter-sets/{parameter_set_id}/approve",
             .permission = Permission::kApprove,
             .audit = Audit::kHandler,
             .json_body = true,
             .tag = "parameter-sets",
             .summary =
                 "Approve a parameter set: it becomes its leg's approved set, the one the model "
                 "gate, tracking and the daily check use (earlier approvals stay in history); "
                 "audited",
             .request_schema = ObjectSchema(
                 {{"note", {{"type", "string"}, {"minLength", 1}, {"maxLength", kMaxNoteLength}}}},
                 {"note"}),
             .handler = [&db](RequestContext& ctx) { return Approve(db, ctx); }});
  table.Add({.method = "GET",
             .path = "/api/v1/subjects/{subject_id}/legs/{leg}/approved-parameter-set",
             .permission = Permission::kRead,
             .tag = "parameter-sets",
             .summary = "The leg's approved parameter set (404 naming how to approve one when "
                        "none is)",
             .handler = [&db](RequestContext& ctx) { return LegApprovedSet(db, ctx); }});
}

}  // namespace fesbench::server::http
