// Sessions: a subject's list, create, get, correct, revisions, and a session's
// runs and trials (docs/API.md).

#include "server/http/api_routes.h"
#include "server/http/resources_json.h"
#include "server/http/routes_common.h"
#include "server/services/run_service.h"
#include "storage/sessions.h"
#include "storage/subjects.h"
#include "storage/trials.h"

namespace fesbench::server::http {

using nlohmann::json;

namespace {

// Sessions: a subject's list, and a new one.
void AddSessionListRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  {
    auto q = PageParams();
    q.push_back({"from", "string", "sessions on or after this date (YYYY-MM-DD)"});
    q.push_back({"to", "string", "sessions before this date (YYYY-MM-DD)"});
    table.Add({.method = "GET",
               .path = "/api/v1/subjects/{subject_id}/sessions",
               .permission = Permission::kRead,
               .tag = "sessions",
               .summary = "A subject's sessions (filter by date range)",
               .query = q,
               .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
                 auto page = ParsePage(ctx);
                 if (!page.ok()) return page.status();
                 auto from = QueryTime(ctx, "from");
                 if (!from.ok()) return from.status();
                 auto to = QueryTime(ctx, "to");
                 if (!to.ok()) return to.status();
                 auto sessions =
                     storage::SessionRepository(db).ListForSubject(ctx.Id("subject_id"));
                 if (!sessions.ok()) return sessions.status();
                 std::vector<storage::Session> kept;
                 for (auto& s : *sessions) {
                   // Session dates are calendar dates: compare as text.
                   const std::string& date = s.current.details.date;
                   if (*from && date < api::FormatUtc(**from).substr(0, 10)) continue;
                   if (*to && date >= api::FormatUtc(**to).substr(0, 10)) continue;
                   kept.push_back(std::move(s));
                 }
                 api::Status failure;
                 json body = MakePage(
                     kept, *page, [](const storage::Session& s) { return s.id; },
                     [&](const storage::Session& s) {
                       auto j = SessionJson(db, s);
                       if (!j.ok()) failure = j.status();
                       return j.ok() ? *j : json(nullptr);
                     });
                 if (!failure.ok()) return failure;
                 return JsonReply(std::move(body));
               }});
  }
  table.Add({.method = "POST",
             .path = "/api/v1/subjects/{subject_id}/sessions",
             .permission = Permission::kRecord,
             .audit = Audit::kHandler,
             .json_body = true,
             .tag = "sessions",
             .summary = "Open a session for one leg of a subject",
             .success_status = 201,
             .request_schema = ObjectSchema(
                 {{"leg", {{"enum", {"left", "right"}}}},
                  {"date", {{"type", "string"}, {"format", "date"}}},
                  {"accelerometer_placement", {{"type", "string"}, {"maxLength", 256}}},
                  {"threshold_ma", {{"type", "number"}, {"minimum", 0}, {"maximum", 100}}},
                  {"max_tolerated_ma", {{"type", "number"}, {"minimum", 0}, {"maximum", 100}}},
                  {"notes", {{"type", "string"}, {"maxLength", 4096}}}},
                 {"leg", "date"}),
             .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
               auto request = NewSessionFromJson(ctx.body);
               if (!request.ok()) return request.status();
               const std::int64_t subject_id = ctx.Id("subject_id");
               auto created = AuditedWrite<json>(
                   db, ctx, 201,
                   [&]() -> api::Result<json> {
                     storage::SubjectRepository subjects(db);
                     auto legs = subjects.Legs(subject_id);
                     if (!legs.ok()) return legs.status();
                     std::optional<std::int64_t> leg_id;
                     for (const auto& leg : *legs) {
                       if (leg.side == request->leg) leg_id = leg.id;
                     }
                     if (!leg_id) {
                       auto leg = subjects.AddLeg(subject_id, request->leg);
                       if (!leg.ok()) return leg.status();
                       leg_id = leg->id;
                     }
                     auto session = storage::SessionRepository(db).Create(subject_id, *leg_id,
                                                                          request->details);
                     if (!session.ok()) return session.status();
                     return api::SessionToJson(storage::SessionResource(*session, request->leg));
                   },
                   [](const json& s) {
                     return "sessions/" + std::to_string(s["id"].get<std::int64_t>());
                   });
               if (!created.ok()) return created.status();
               return JsonReply(std::move(*created), 201);
             }});
}

// One session: get, correct, revisions.
void AddSessionRecordRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  table.Add({.method = "GET",
             .path = "/api/v1/sessions/{session_id}",
             .permission = Permission::kRead,
             .tag = "sessions",
             .summary = "One session",
             .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
               auto session = storage::SessionRepository(db).Get(ctx.Id("session_id"));
               if (!session.ok()) return session.status();
               auto j = SessionJson(db, *session);
               if (!j.ok()) return j.status();
               return JsonReply(std::move(*j));
             }});
  table.Add(
      {.method = "PATCH",
       .path = "/api/v1/sessions/{session_id}",
       .permission = Permission::kRecord,
       .audit = Audit::kHandler,
       .json_body = true,
       .tag = "sessions",
       .summary = "Correct a session's details: a new revision with a reason (given fields replace "
                  "the current ones, null clears one); audited",
       .request_schema = CorrectionSchema(ObjectSchema(
           {{"date", {{"type", "string"}, {"format", "date"}}},
            {"accelerometer_placement", {{"type", {"string", "null"}}, {"maxLength", 256}}},
            {"threshold_ma", {{"type", {"number", "null"}}, {"minimum", 0}, {"maximum", 100}}},
            {"max_tolerated_ma", {{"type", {"number", "null"}}, {"minimum", 0}, {"maximum", 100}}},
            {"notes", {{"type", {"string", "null"}}, {"maxLength", 4096}}}},
           {})),
       .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
         const std::int64_t id = ctx.Id("session_id");
         storage::SessionRepository sessions(db);
         auto current = sessions.Get(id);
         if (!current.ok()) return current.status();
         auto correction = SessionCorrectionFromJson(ctx.body, current->current.details);
         if (!correction.ok()) return correction.status();
         auto corrected = AuditedCorrection(
             db, ctx, "sessions/" + std::to_string(id), correction->reason, correction->changed,
             api::SessionDetailsToJson(correction->details), [&]() -> api::Result<json> {
               auto s = sessions.Correct(id, correction->details, correction->reason,
                                         ctx.user ? ctx.user->name : std::string());
               if (!s.ok()) return s.status();
               return SessionJson(db, *s);
             });
         if (!corrected.ok()) return corrected.status();
         return JsonReply(std::move(*corrected));
       }});
  table.Add({.method = "GET",
             .path = "/api/v1/sessions/{session_id}/revisions",
             .permission = Permission::kRead,
             .tag = "sessions",
             .summary = "A session's revisions, oldest first (who, when, why, the details)",
             .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
               auto revisions = storage::SessionRepository(db).Revisions(ctx.Id("session_id"));
               if (!revisions.ok()) return revisions.status();
               return JsonReply(RevisionsJson(storage::RevisionResources(*revisions), &api::SessionRevisionToJson));
             }});
}

// A session's runs and trials, paged.
void AddSessionRunAndTrialRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  table.Add(
      {.method = "GET",
       .path = "/api/v1/sessions/{session_id}/runs",
       .permission = Permission::kRead,
       .tag = "runs",
       .summary = "The runs of a session (history; each item has the shape of GET /runs/{id})",
       .query = PageParams(),
       .handler = [&db, runs_service = deps.runs](RequestContext& ctx) -> api::Result<Reply> {
         auto page = ParsePage(ctx);
         if (!page.ok()) return page.status();
         storage::SessionRepository sessions(db);
         if (auto s = sessions.Get(ctx.Id("session_id")); !s.ok()) return s.status();
         auto runs = sessions.ListRunsPage(ctx.Id("session_id"), page->after_id, page->limit + 1);
         if (!runs.ok()) return runs.status();
         api::Status failure;
         json body = MakePage(
             *runs, *page, [](const storage::Run& r) { return r.id; },
             [&](const storage::Run& r) -> json {
               if (!runs_service) return api::RunViewToJson(storage::RunViewOf(r));
               auto view = runs_service->Get(r.id);
               if (!view.ok()) {
                 failure = view.status();
                 return nullptr;
               }
               return api::RunViewToJson(*view);
             });
         if (!failure.ok()) return failure;
         return JsonReply(std::move(body));
       }});
  table.Add({.method = "GET",
             .path = "/api/v1/sessions/{session_id}/trials",
             .permission = Permission::kRead,
             .tag = "trials",
             .summary = "The trials recorded in a session (summaries)",
             .query = PageParams(),
             .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
               auto page = ParsePage(ctx);
               if (!page.ok()) return page.status();
               if (auto s = storage::SessionRepository(db).Get(ctx.Id("session_id")); !s.ok()) {
                 return s.status();
               }
               auto trials = storage::TrialRepository(db).ListForSessionPage(
                   ctx.Id("session_id"), page->after_id, page->limit + 1);
               if (!trials.ok()) return trials.status();
               return JsonReply(MakePage(
                   *trials, *page, [](const storage::TrialSummary& t) { return t.id; },
                   api::TrialSummaryToJson));
             }});
}

}  // namespace

void AddSessionRoutes(RouteTable& table, const ApiDependencies& deps) {
  AddSessionListRoutes(table, deps);
  AddSessionRecordRoutes(table, deps);
  AddSessionRunAndTrialRoutes(table, deps);
}

}  // namespace fesbench::server::http
