// Bench and run routes: start / read / cancel / heartbeat runs, the live
// event stream, bench state, e-stop, the virtual subject (docs/API.md; docs/SAFETY.md).

#include <chrono>
#include <utility>

#include "api/run_start.h"
#include "server/http/api_routes.h"
#include "server/http/auth.h"
#include "server/http/routes_common.h"
#include "server/protocols/protocol.h"
#include "server/services/bench_service.h"
#include "server/services/run_service.h"
#include "server/services/sample_hub.h"

namespace fesbench::server::http {

namespace {

using nlohmann::json;

// One Server-Sent Events frame.
std::string SseFrame(std::uint64_t id, std::string_view event, const json& data) {
  std::string frame;
  if (id != 0) frame += "id: " + std::to_string(id) + "\n";
  frame += "event: ";
  frame += event;
  frame += "\ndata: ";
  frame += data.dump(-1, ' ', false, json::error_handler_t::replace);
  frame += "\n\n";
  return frame;
}

// The state of one open stream, owned by the content provider.
struct EventStream {
  std::unique_ptr<StreamSlots::Slot> slot;
  std::unique_ptr<services::Subscription> subscription;
  std::string pending;  // frames to send before reading the hub
  bool finished = false;
  /// An endless stream ends here (the client reconnects); unset: at its end item.
  std::optional<std::chrono::steady_clock::time_point> deadline;
  std::chrono::steady_clock::time_point last_write = std::chrono::steady_clock::now();
};

// Sends `stream`'s pending frames, then its subscription's items as SSE,
// until an end item, the subscription closing, the server shutting down or
// the viewer leaving (a failed write frees the worker at once). A comment
// line every 2 s of silence keeps proxies open and detects a departed viewer.
api::Result<Reply> ServeEventStream(RequestContext& ctx, std::shared_ptr<EventStream> stream,
                                    StreamSlots* slots) {
  ctx.res.status = 200;
  ctx.res.set_header("X-Accel-Buffering", "no");
  ctx.res.set_event_stream(
      "text/event-stream",
      [stream, slots](EventSink& sink) {
        using namespace std::chrono;
        auto write = [&](const std::string& text) {
          stream->last_write = steady_clock::now();
          return sink.write(text);
        };
        if (!stream->pending.empty()) {
          std::string pending = std::move(stream->pending);
          stream->pending.clear();
          if (!write(pending)) return false;
        }
        if (stream->finished || slots->shutting_down() || !stream->subscription ||
            (stream->deadline && steady_clock::now() >= *stream->deadline)) {
          sink.done();
          return true;
        }
        // Wait briefly for the next item, then send what has queued up.
        std::string frames;
        bool end = false;
        auto item = stream->subscription->Next(milliseconds(250));
        for (int n = 0; item && n < 256; ++n) {
          json data = api::RunEventToJson(*item);
          if (item->kind == services::HubItem::Kind::kEnd) {
            data["dropped"] = stream->subscription->dropped();
            end = true;
          }
          frames += SseFrame(item->seq, api::RunEventKindName(item->kind), data);
          if (end) break;
          item = stream->subscription->Next(milliseconds(0));
        }
        if (!frames.empty()) {
          if (!write(frames)) return false;  // the viewer left: free the worker
        } else if (steady_clock::now() - stream->last_write > seconds(2)) {
          if (!write(": keep-alive\n\n")) return false;
        }
        if (end || stream->subscription->closed()) {
          stream->finished = true;
          sink.done();
        }
        return true;
      });
  return Reply{200, nullptr, true};
}

json RunViewJson(const services::RunView& view) { return api::RunViewToJson(view); }

// PUT /bench/virtual-subject: a seeded draw of a shape family, or a full
// subject (api/virtual_subject.h).
json VirtualSubjectPutSchema() {
  const json draw = {
      {"type", "object"},
      {"required", {"draw_seed"}},
      {"additionalProperties", false},
      {"properties",
       {{"draw_seed", {{"type", "integer"}, {"minimum", 0}}},
        {"family",
         {{"type", "string"},
          {"enum", {"thesis", "analytic", "plateau"}},
          {"default", "thesis"},
          {"description",
           "thesis: the server's generator; analytic: gravity + exponential end-range "
           "stiffness, asymmetric damping, other Gaussian f_ata, tanh f_atv; plateau: a "
           "recruitment that plateaus below full activation, steep stiffness at both ends, "
           "strong potentiation, slow recovery"}}}}}};
  const json full = {{"type", "object"},
                     {"required", {"truth", "threshold_ma", "max_tolerated_ma"}},
                     {"description", "a full virtual subject (docs/ARCHITECTURE.md, The benches)"}};
  return {{"oneOf", {draw, full}}};
}

// Runs: start, get, cancel, stop, heartbeat.
void AddRunRoutes(RouteTable& table, const ApiDependencies& deps) {
  services::RunService* runs = deps.runs;
  table.Add(
      {.method = "POST",
       .path = "/api/v1/sessions/{session_id}/runs",
       .permission = Permission::kOperateBench,
       .audit = Audit::kHandler,
       .json_body = true,
       .tag = "runs",
       .summary = "Start a protocol for a session (one run at a time; 409 while the bench is busy)",
       .success_status = 201,
       .request_schema = ObjectSchema(
           {{"protocol", {{"type", "string"}}},
            {"parameters",
             {{"type", "object"},
              {"additionalProperties",
               {{"type", {"number", "string"}},
                {"description", "a number; a choice parameter also its name"}}}}},
            {"ceiling_reason", {{"type", "string"}, {"maxLength", 500}}},
            {"target_samples",
             {{"type", "object"},
              {"description",
               "tracking with parameters.target = uploaded: the trajectory, "
               "t_s (strictly increasing) and angle_deg, ≤ 40000 samples each"},
              {"properties",
               {{"t_s", {{"type", "array"}, {"items", {{"type", "number"}}}}},
                {"angle_deg", {{"type", "array"}, {"items", {{"type", "number"}}}}}}}}}},
           {"protocol"}),
       .handler = [runs](RequestContext& ctx) -> api::Result<Reply> {
         if (!runs) return NotAvailable("the bench");
         api::Result<api::StartRunRequest> read = api::StartRunRequestFromJson(ctx.body);
         if (!read.ok()) return read.status();
         auto request = protocols::ResolveChoiceNames(std::move(read).value());
         if (!request.ok()) return request.status();
         auto view = runs->Start(ActorOf(*ctx.user), ctx.Id("session_id"), request->protocol,
                                 request->parameters, request->ceiling_reason,
                                 request->target ? &*request->target : nullptr);
         if (!view.ok()) return view.status();
         ctx.res.set_header("Location", "/api/v1/runs/" + std::to_string(view->run_id));
         return JsonReply(RunViewJson(*view), 201);
       }});
  table.Add({.method = "GET",
             .path = "/api/v1/runs/{run_id}",
             .permission = Permission::kRead,
             .tag = "runs",
             .summary = "A run's state, progress (fraction, ETA), trials and result",
             .handler = [runs](RequestContext& ctx) -> api::Result<Reply> {
               if (!runs) return NotAvailable("the bench");
               auto view = runs->Get(ctx.Id("run_id"));
               if (!view.ok()) return view.status();
               return JsonReply(RunViewJson(*view));
             }});
  table.Add({.method = "POST",
             .path = "/api/v1/runs/{run_id}/cancel",
             .permission = Permission::kOperateBench,
             .audit = Audit::kHandler,
             .tag = "runs",
             .summary = "Cancel the run in progress (stimulation to zero)",
             .handler = [runs](RequestContext& ctx) -> api::Result<Reply> {
               if (!runs) return NotAvailable("the bench");
               if (auto st = runs->Cancel(ActorOf(*ctx.user), ctx.Id("run_id")); !st.ok())
                 return st;
               auto view = runs->Get(ctx.Id("run_id"));
               if (!view.ok()) return view.status();
               return JsonReply(RunViewJson(*view));
             }});
  table.Add({.method = "POST",
             .path = "/api/v1/runs/{run_id}/stop",
             .permission = Permission::kOperateBench,
             .audit = Audit::kHandler,
             .tag = "runs",
             .summary = "Stop with result (tolerance_test keeps the amplitude reached)",
             .handler = [runs](RequestContext& ctx) -> api::Result<Reply> {
               if (!runs) return NotAvailable("the bench");
               if (auto st = runs->StopWithResult(ActorOf(*ctx.user), ctx.Id("run_id")); !st.ok()) {
                 return st;
               }
               auto view = runs->Get(ctx.Id("run_id"));
               if (!view.ok()) return view.status();
               return JsonReply(RunViewJson(*view));
             }});
  table.Add({.method = "POST",
             .path = "/api/v1/runs/{run_id}/heartbeat",
             .permission = Permission::kOperateBench,
             .audit = Audit::kNever,
             .tag = "runs",
             .summary = "Heartbeat of the controlling user (at least once per second during a run; "
                        "not audited: it changes nothing)",
             .handler = [runs](RequestContext& ctx) -> api::Result<Reply> {
               if (!runs) return NotAvailable("the bench");
               if (auto st = runs->Heartbeat(ActorOf(*ctx.user), ctx.Id("run_id")); !st.ok()) {
                 return st;
               }
               return JsonReply({{"run_id", ctx.Id("run_id")}, {"ok", true}});
             }});
}

// Event streams: a run's samples and states, new parameter sets.
void AddStreamRoutes(RouteTable& table, const ApiDependencies& deps) {
  services::RunService* runs = deps.runs;
  services::SampleHub* hub = deps.samples;
  StreamSlots* slots = deps.streams;
  table.Add({.method = "GET",
             .path = "/api/v1/runs/{run_id}/stream",
             .permission = Permission::kRead,
             .tag = "runs",
             .summary = "Server-Sent Events of a run: state, progress, samples (batched, with "
                        "first_sample), trial, end",
             .produces = "text/event-stream",
             .handler = [runs, hub, slots](RequestContext& ctx) -> api::Result<Reply> {
               if (!runs || !hub) return NotAvailable("the bench");
               const std::int64_t run_id = ctx.Id("run_id");
               auto slot = slots->TryAcquire();
               if (!slot)
                 return api::Status::Unavailable("too many open event streams; retry later");
               auto stream = std::make_shared<EventStream>();
               stream->slot = std::move(slot);
               services::SubscribeOptions options;
               options.run_id = run_id;
               stream->subscription = hub->Subscribe(options);
               auto view = runs->Get(run_id);
               if (!view.ok()) return view.status();
               if (protocols::IsFinal(view->state)) {
                 // A finished run: its final state, then the end.
                 json state = {{"run_id", run_id},
                               {"kind", "state"},
                               {"state", protocols::RunStateName(view->state)},
                               {"reason", view->reason}};
                 json end = state;
                 end["kind"] = "end";
                 end["parameter_set_id"] =
                     view->parameter_set_id ? json(*view->parameter_set_id) : json(nullptr);
                 end["result"] = view->result;
                 end["dropped"] = 0;
                 stream->pending = SseFrame(0, "state", state) + SseFrame(0, "end", end);
                 stream->finished = true;
                 stream->subscription.reset();
               }
               return ServeEventStream(ctx, std::move(stream), slots);
             }});
  table.Add(
      {.method = "GET",
       .path = "/api/v1/events/parameter-sets",
       .permission = Permission::kRead,
       .tag = "parameter-sets",
       .summary = "Server-Sent Events: one parameter_set event (parameter_set_id, subject_id, "
                  "leg_id) for every parameter set stored from now on, by a run, an "
                  "identification job or an import; the stream ends after timeout_s",
       .query = {{"timeout_s", "integer",
                  "seconds until the stream ends and the client reconnects, 1–3600 (default 300)"}},
       .produces = "text/event-stream",
       .handler = [hub, slots](RequestContext& ctx) -> api::Result<Reply> {
         if (!hub) return NotAvailable("the event hub");
         auto timeout = QueryId(ctx, "timeout_s");
         if (!timeout.ok() || (*timeout && **timeout > 3600)) {
           return api::Status::InvalidArgument(
               "must be 1–3600 s, got " + ctx.Query("timeout_s").value_or(""), "timeout_s");
         }
         auto slot = slots->TryAcquire();
         if (!slot) return api::Status::Unavailable("too many open event streams; retry later");
         auto stream = std::make_shared<EventStream>();
         stream->slot = std::move(slot);
         services::SubscribeOptions options;
         options.kind = services::HubItem::Kind::kParameterSet;
         options.stored_sets_only = true;
         stream->subscription = hub->Subscribe(options);
         stream->deadline =
             std::chrono::steady_clock::now() + std::chrono::seconds(timeout->value_or(300));
         return ServeEventStream(ctx, std::move(stream), slots);
       }});
}

// The bench: its state, e-stop and clearing it, the virtual subject.
void AddBenchStateRoutes(RouteTable& table, const ApiDependencies& deps) {
  services::RunService* runs = deps.runs;
  services::BenchService* bench = deps.bench;
  table.Add({.method = "GET",
             .path = "/api/v1/bench",
             .permission = Permission::kRead,
             .tag = "bench",
             .summary = "The bench: kind, limits, mode, e-stop, owner, current run and progress",
             .handler = [bench](RequestContext&) -> api::Result<Reply> {
               if (!bench) return NotAvailable("the bench");
               return JsonReply(services::BenchInfoToJson(bench->Info()));
             }});
  table.Add({.method = "POST",
             .path = "/api/v1/bench/estop",
             .permission = Permission::kEStop,
             .audit = Audit::kHandler,
             .tag = "bench",
             .summary = "Emergency stop: stimulation to zero and motor disabled at once; latches "
                        "(any signed-in user may press it)",
             .handler = [runs](RequestContext& ctx) -> api::Result<Reply> {
               if (!runs) return NotAvailable("the bench");
               if (auto st = runs->EStop(ActorOf(*ctx.user), "http"); !st.ok()) return st;
               return JsonReply(api::BenchStateToJson(runs->State()));
             }});
  table.Add({.method = "DELETE",
             .path = "/api/v1/bench/estop",
             .permission = Permission::kOperateBench,
             .audit = Audit::kHandler,
             .tag = "bench",
             .summary = "Clear a latched e-stop",
             .handler = [runs](RequestContext& ctx) -> api::Result<Reply> {
               if (!runs) return NotAvailable("the bench");
               if (auto st = runs->ClearEStop(ActorOf(*ctx.user)); !st.ok()) return st;
               return JsonReply(api::BenchStateToJson(runs->State()));
             }});
  table.Add({.method = "GET",
             .path = "/api/v1/bench/virtual-subject",
             .permission = Permission::kAdminister,
             .tag = "bench",
             .summary = "The simulated bench's virtual subject (truth JSON); 409 on a real bench",
             .handler = [bench](RequestContext& ctx) -> api::Result<Reply> {
               if (!bench) return NotAvailable("the bench");
               auto subject = bench->GetVirtualSubject(ActorOf(*ctx.user));
               if (!subject.ok()) return subject.status();
               return JsonReply(std::move(*subject));
             }});
  table.Add({.method = "PUT",
             .path = "/api/v1/bench/virtual-subject",
             .permission = Permission::kAdminister,
             .audit = Audit::kHandler,
             .json_body = true,
             .tag = "bench",
             .summary =
                 "Replace the virtual subject between runs: a full subject, or {\"draw_seed\": N, "
                 "\"family\": F} (N a non-negative integer; F \"thesis\", the default, or "
                 "\"analytic\": gravity + exponential end-range stiffness, asymmetric damping, "
                 "other Gaussian f_ata, tanh f_atv, or \"plateau\": a recruitment that plateaus "
                 "below full activation, steep stiffness at both ends; no other key) for the "
                 "server's seeded draw "
                 "(simulation only; 409 on a real bench or while a run holds the bench)",
             .request_schema = VirtualSubjectPutSchema(),
             .handler = [bench](RequestContext& ctx) -> api::Result<Reply> {
               if (!bench) return NotAvailable("the bench");
               auto subject = bench->PutVirtualSubject(ActorOf(*ctx.user), ctx.body);
               if (!subject.ok()) return subject.status();
               return JsonReply(std::move(*subject));
             }});
}

}  // namespace

void AddBenchRoutes(RouteTable& table, const ApiDependencies& deps) {
  AddRunRoutes(table, deps);
  AddStreamRoutes(table, deps);
  AddBenchStateRoutes(table, deps);
}

}  // namespace fesbench::server::http
