// Subjects: list, create, get, correct, revisions (docs/API.md).

#include "server/http/api_routes.h"
#include "server/http/resources_json.h"
#include "server/http/routes_common.h"
#include "storage/subjects.h"

namespace fesbench::server::http {

using nlohmann::json;

namespace {

json DetailsSchema() {
  return ObjectSchema(
      {{"age_years", {{"type", "integer"}, {"minimum", 0}, {"maximum", 130}}},
       {"sex", {{"enum", {"female", "male", "other", "undisclosed"}}}},
       {"height_cm", {{"type", "number"}, {"minimum", 30}, {"maximum", 250}}},
       {"weight_kg", {{"type", "number"}, {"minimum", 1}, {"maximum", 400}}},
       {"shank_length_cm", {{"type", "number"}, {"minimum", 10}, {"maximum", 80}}},
       {"calf_circumference_cm", {{"type", "number"}, {"minimum", 10}, {"maximum", 100}}},
       {"rom_min_deg", {{"type", "number"}, {"minimum", -30}, {"maximum", 60}}},
       {"rom_max_deg", {{"type", "number"}, {"minimum", 60}, {"maximum", 180}}}},
      {});
}

}  // namespace

// Subjects: list, create, get, correct, revisions.
void AddSubjectRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  {
    auto q = PageParams();
    q.push_back({"code", "string", "exact pseudonymous code"});
    table.Add({.method = "GET",
               .path = "/api/v1/subjects",
               .permission = Permission::kRead,
               .tag = "subjects",
               .summary = "List subjects",
               .query = q,
               .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
                 auto page = ParsePage(ctx);
                 if (!page.ok()) return page.status();
                 storage::SubjectRepository subjects(db);
                 std::vector<storage::Subject> list;
                 if (auto code = ctx.Query("code")) {
                   if (auto st = storage::ValidateSubjectCode(*code); !st.ok()) return st;
                   auto one = subjects.GetByCode(*code);
                   if (one.ok()) {
                     list.push_back(*one);
                   } else if (one.status().code() != api::ErrorCode::kNotFound) {
                     return one.status();
                   }
                 } else {
                   // One row beyond the page says whether a next page exists.
                   auto rows = subjects.ListPage(page->after_id, page->limit + 1);
                   if (!rows.ok()) return rows.status();
                   list = std::move(*rows);
                 }
                 api::Status failure;
                 json body = MakePage(
                     list, *page, [](const storage::Subject& s) { return s.id; },
                     [&](const storage::Subject& s) {
                       auto j = SubjectJson(db, s);
                       if (!j.ok()) {
                         failure = j.status();
                         return json(nullptr);
                       }
                       return *j;
                     });
                 if (!failure.ok()) return failure;
                 return JsonReply(std::move(body));
               }});
  }
  table.Add({.method = "POST",
             .path = "/api/v1/subjects",
             .permission = Permission::kRecord,
             .audit = Audit::kHandler,
             .json_body = true,
             .tag = "subjects",
             .summary = "Create a subject (pseudonymous code, anthropometrics, legs)",
             .success_status = 201,
             .request_schema = ObjectSchema(
                 {{"code", {{"type", "string"}, {"pattern", "^[A-Za-z0-9_-]{1,32}$"}}},
                  {"details", DetailsSchema()},
                  {"legs",
                   {{"type", "array"}, {"items", {{"enum", {"left", "right"}}}}, {"maxItems", 2}}}},
                 {"code"}),
             .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
               auto request = NewSubjectFromJson(ctx.body);
               if (!request.ok()) return request.status();
               auto created = AuditedWrite<json>(
                   db, ctx, 201,
                   [&]() -> api::Result<json> {
                     storage::SubjectRepository subjects(db);
                     auto subject = subjects.Create(request->code, request->details);
                     if (!subject.ok()) return subject.status();
                     for (auto side : request->legs) {
                       if (auto leg = subjects.AddLeg(subject->id, side); !leg.ok()) {
                         return leg.status();
                       }
                     }
                     return SubjectJson(db, *subject);
                   },
                   [](const json& s) {
                     return "subjects/" + std::to_string(s["id"].get<std::int64_t>());
                   });
               if (!created.ok()) return created.status();
               return JsonReply(std::move(*created), 201);
             }});
  table.Add({.method = "GET",
             .path = "/api/v1/subjects/{subject_id}",
             .permission = Permission::kRead,
             .tag = "subjects",
             .summary = "One subject with its current details and legs",
             .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
               auto subject = storage::SubjectRepository(db).Get(ctx.Id("subject_id"));
               if (!subject.ok()) return subject.status();
               auto j = SubjectJson(db, *subject);
               if (!j.ok()) return j.status();
               return JsonReply(std::move(*j));
             }});

  table.Add(
      {.method = "PATCH",
       .path = "/api/v1/subjects/{subject_id}",
       .permission = Permission::kRecord,
       .audit = Audit::kHandler,
       .json_body = true,
       .tag = "subjects",
       .summary = "Correct a subject's details: a new revision with a reason (given fields replace "
                  "the current ones, null clears one); audited",
       .request_schema = CorrectionSchema(DetailsSchema()),
       .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
         const std::int64_t id = ctx.Id("subject_id");
         storage::SubjectRepository subjects(db);
         auto current = subjects.Get(id);
         if (!current.ok()) return current.status();
         auto correction = SubjectCorrectionFromJson(ctx.body, current->current.details);
         if (!correction.ok()) return correction.status();
         auto corrected = AuditedCorrection(
             db, ctx, "subjects/" + std::to_string(id), correction->reason, correction->changed,
             api::SubjectDetailsToJson(correction->details), [&]() -> api::Result<json> {
               auto s = subjects.Correct(id, correction->details, correction->reason,
                                         ctx.user ? ctx.user->name : std::string());
               if (!s.ok()) return s.status();
               return SubjectJson(db, *s);
             });
         if (!corrected.ok()) return corrected.status();
         return JsonReply(std::move(*corrected));
       }});
  table.Add({.method = "GET",
             .path = "/api/v1/subjects/{subject_id}/revisions",
             .permission = Permission::kRead,
             .tag = "subjects",
             .summary = "A subject's revisions, oldest first (who, when, why, the details)",
             .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
               auto revisions = storage::SubjectRepository(db).Revisions(ctx.Id("subject_id"));
               if (!revisions.ok()) return revisions.status();
               return JsonReply(RevisionsJson(storage::RevisionResources(*revisions), &api::SubjectRevisionToJson));
             }});
}

}  // namespace fesbench::server::http
