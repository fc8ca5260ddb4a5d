// Job routes: identifications, predictions and comparisons run in the
// bounded job pool, never on the bench's control path (docs/API.md, "Jobs").
// A submission answers 202 with the job record (Location: /api/v1/jobs/{id});
// GET /jobs/{id} follows it to "done" (result) or "failed" (error).

#include "server/http/api_routes.h"
#include "server/http/auth.h"
#include "server/http/routes_common.h"
#include "server/services/analysis_json.h"
#include "server/services/comparison_service.h"
#include "server/services/identification_service.h"
#include "server/services/job_pool.h"
#include "server/services/prediction_service.h"
#include "storage/parameter_sets.h"

namespace fesbench::server::http {

namespace {

using nlohmann::json;

api::Result<Reply> Submitted(RequestContext& ctx, services::JobPool& jobs,
                             const api::Result<std::int64_t>& id) {
  if (!id.ok()) return id.status();
  auto record = jobs.Get(*id);
  if (!record.ok()) return record.status();
  ctx.res.set_header("Location", "/api/v1/jobs/" + std::to_string(*id));
  return JsonReply(services::JobToJson(*record), 202);
}

json IdSchema() { return {{"type", "integer"}, {"minimum", 1}}; }

}  // namespace

void AddJobRoutes(RouteTable& table, const ApiDependencies& deps) {
  services::JobPool* jobs = deps.jobs;
  services::IdentificationService* identification = deps.identification;
  services::PredictionService* prediction = deps.prediction;
  services::ComparisonService* comparison = deps.comparison;

  table.Add({.method = "POST",
             .path = "/api/v1/identifications",
             .permission = Permission::kAnalyse,
             .json_body = true,
             .tag = "jobs",
             .summary = "Fit a model from stored trials (a session's, or listed trial ids); a job",
             .success_status = 202,
             .request_schema = ObjectSchema(
                 {{"session_id", IdSchema()},
                  {"trial_ids", {{"type", "array"}, {"items", IdSchema()}}},
                  {"method", {{"enum", {"thesis", "rapid"}}}},
                  {"irc_method", {{"type", "string"}}},
                  {"passive_method", {{"enum", {"sequential", "simultaneous", "free_swing"}}}},
                  {"contraction_order", {{"enum", {0, 2, 3}}}},
                  {"pole_method", {{"enum", {"peak", "least_squares"}}}},
                  {"models", {{"type", "array"}, {"items", {{"type", "string"}}}}},
                  {"breakpoints", {{"type", "object"}}},
                  {"inertia_kgm2", {{"type", "number"}, {"exclusiveMinimum", 0}}},
                  {"torque_angle_parameter_set_id", IdSchema()}},
                 {}),
             .handler = [jobs, identification](RequestContext& ctx) -> api::Result<Reply> {
               if (!jobs || !identification) return NotAvailable("identification");
               auto request = services::ReadIdentificationRequest(ctx.body);
               if (!request.ok()) return request.status();
               return Submitted(ctx, *jobs,
                                services::SubmitIdentification(*jobs, *identification,
                                                               ActorOf(*ctx.user), *request));
             }});
  table.Add(
      {.method = "POST",
       .path = "/api/v1/predictions",
       .permission = Permission::kPredict,  // the clinician's model check
       .json_body = true,
       .tag = "jobs",
       .summary = "Simulate a parameter set on a named stimulus or a stored trial (with errors "
                  "against it); free swing stops at the bench's range of motion; fit_scale "
                  "(isometric trial) scales the torque by the best-fit constant of §6.1.2; a job",
       .success_status = 202,
       .request_schema = ObjectSchema(
           {{"parameter_set_id", IdSchema()},
            {"trial_id", IdSchema()},
            {"stimulus",
             ObjectSchema({{"generator", {{"type", "string"}}}, {"params", {{"type", "object"}}}},
                          {"generator"})},
            {"mode", {{"enum", {"free_swing", "isometric"}}}},
            {"initial_angle_deg", {{"type", "number"}}},
            {"initial_velocity_deg_s", {{"type", "number"}}},
            {"duration_s", {{"type", "number"}}},
            {"fit_scale", {{"type", "boolean"}}}},
           {"parameter_set_id"}),
       .handler = [jobs, prediction](RequestContext& ctx) -> api::Result<Reply> {
         if (!jobs || !prediction) return NotAvailable("prediction");
         auto request = services::ReadPredictionRequest(ctx.body);
         if (!request.ok()) return request.status();
         return Submitted(
             ctx, *jobs,
             services::SubmitPrediction(*jobs, *prediction, ActorOf(*ctx.user), *request));
       }});
  storage::Database* db = deps.db;
  table.Add(
      {.method = "POST",
       .path = "/api/v1/parameter-sets/{parameter_set_id}/model-check",
       .permission = Permission::kPredict,
       .tag = "jobs",
       .summary = "The model check: the set predicts its leg's validation trials it was not "
                  "fitted on (each stored as a prediction); E_RMS in each trial's quantity "
                  "judged against the thresholds of docs/MODEL.md, a verdict "
                  "(good_for_control, use_with_care, do_not_use, no_fresh_trials) and the fit "
                  "warnings in a clinician's words; a job",
       .success_status = 202,
       .handler = [jobs, prediction, db](RequestContext& ctx) -> api::Result<Reply> {
         if (!jobs || !prediction || !db) return NotAvailable("the model check");
         const std::int64_t id = ctx.Id("parameter_set_id");
         // An unknown set is a 404 now, not a failed job later.
         if (auto set = storage::ParameterSetRepository(*db).Get(id); !set.ok()) {
           return set.status();
         }
         return Submitted(ctx, *jobs,
                          services::SubmitModelCheck(*jobs, *db, *prediction,
                                                     ActorOf(*ctx.user), id));
       }});
  table.Add(
      {.method = "POST",
       .path = "/api/v1/comparisons",
       .permission = Permission::kAnalyse,
       .json_body = true,
       .tag = "jobs",
       .summary = "Each pair's errors under two parameter sets (or models) over its trials, "
                  "and their paired t-test where it is defined (2 pairs or more; else t_test "
                  "null and t_test_note says why); a job",
       .success_status = 202,
       .request_schema = ObjectSchema(
           {{"pairs",
             {{"type", "array"},
              {"items", ObjectSchema({{"a_parameter_set_id", IdSchema()},
                                      {"b_parameter_set_id", IdSchema()},
                                      {"trial_ids", {{"type", "array"}, {"items", IdSchema()}}}},
                                     {"a_parameter_set_id", "b_parameter_set_id", "trial_ids"})}}},
            {"metric", {{"type", "string"}}},
            {"confidence", {{"type", "number"}}}},
           {"pairs"}),
       .handler = [jobs, comparison](RequestContext& ctx) -> api::Result<Reply> {
         if (!jobs || !comparison) return NotAvailable("comparison");
         auto request = services::ReadComparisonRequest(ctx.body);
         if (!request.ok()) return request.status();
         return Submitted(
             ctx, *jobs,
             services::SubmitComparison(*jobs, *comparison, ActorOf(*ctx.user), *request));
       }});

  table.Add({.method = "GET",
             .path = "/api/v1/jobs",
             .permission = Permission::kAnalyse,
             .tag = "jobs",
             .summary = "Recent jobs (identifications, predictions, comparisons), newest first",
             .query = {{"limit", "integer", "at most this many, 1–500 (default 50)"}},
             .handler = [jobs](RequestContext& ctx) -> api::Result<Reply> {
               if (!jobs) return NotAvailable("the job pool");
               auto page = ParsePage(ctx);
               if (!page.ok()) return page.status();
               json items = json::array();
               for (const auto& record : jobs->List(page->limit)) {
                 items.push_back(services::JobToJson(record));
               }
               return JsonReply({{"items", std::move(items)}, {"next_cursor", nullptr}});
             }});
  table.Add({.method = "GET",
             .path = "/api/v1/jobs/{job_id}",
             .permission = Permission::kPredict,  // a clinician follows a prediction
             .tag = "jobs",
             .summary = "A job: state (queued, running, done, failed) and result or error",
             .handler = [jobs](RequestContext& ctx) -> api::Result<Reply> {
               if (!jobs) return NotAvailable("the job pool");
               auto record = jobs->Get(ctx.Id("job_id"));
               if (!record.ok()) return record.status();
               return JsonReply(services::JobToJson(*record));
             }});
}

}  // namespace fesbench::server::http
