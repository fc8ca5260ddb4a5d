// Data in and out of a session (services/session_archive.h): POST
// /sessions/{id}/trials imports a recording or a session archive, read
// within bounds (services/import_upload.h), GET /sessions/{id}/export
// writes one.

#include <algorithm>
#include <cctype>
#include <memory>
#include <optional>

#include "api/trial_kind.h"
#include "server/http/api_routes.h"
#include "server/http/resources_json.h"
#include "server/http/routes_common.h"
#include "server/protocols/protocol_registry.h"
#include "server/services/import_upload.h"
#include "server/services/memory_budget.h"
#include "server/services/run_service.h"
#include "server/services/session_archive.h"
#include "server/services/session_report.h"
#include "storage/sessions.h"
#include "storage/subjects.h"
#include "api/time_utc.h"
#include "storage/trials.h"

namespace fesbench::server::http {
namespace {

using nlohmann::json;

std::string MediaType(const Request& req) {
  std::string type = req.get_header_value("Content-Type");
  type = type.substr(0, type.find(';'));
  while (!type.empty() && type.back() == ' ') type.pop_back();
  std::transform(type.begin(), type.end(), type.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return type;
}

// The memory every import in flight draws from together (docs/SAFETY.md
// "Uploads"): unpacked archive entries, recordings' text and what reading
// them holds. 192 MiB keeps three concurrent uploads within the 256 MiB the
// server may grow by for imports, the rest being transient buffers.
constexpr std::size_t kImportMemoryBytes = std::size_t{192} << 20;

json ImportSchema() {
  json column = ObjectSchema({{"column", {{"type", "string"}}},
                              {"channel", {{"type", "string"}}},
                              {"unit", {{"type", "string"}}}},
                             {"column", "channel"});
  json spec = ObjectSchema(
      {{"kind", {{"type", "string"}, {"description", "trial kind (GET /trial-kinds)"}}},
       {"format", {{"enum", {"csv", "tsv", "sto"}}}},
       {"time_column", {{"type", "string"}}},
       {"time_unit", {{"enum", {"s", "ms", "us"}}}},
       {"sample_rate_hz", {{"type", "number"}, {"exclusiveMinimum", 0}}},
       {"columns", {{"type", "array"}, {"items", column}}},
       {"ignore", {{"type", "array"}, {"items", {{"type", "string"}}}}},
       {"start_time_unix_ms", {{"type", "integer"}}},
       {"source", {{"type", "string"}, {"maxLength", 500}}}},
      {"kind"});
  json schema = ObjectSchema({{"spec", spec}, {"data", {{"type", "string"}}}}, {"spec", "data"});
  schema["description"] =
      "A recording as JSON {spec, data: the file's text}; or a session archive (GET "
      "/sessions/{id}/export) sent as the body with Content-Type application/zip or "
      "application/gzip";
  return schema;
}

api::Result<json> RunsJson(storage::Database& db, services::RunService* runs_service,
                           std::int64_t session_id) {
  auto runs = storage::SessionRepository(db).ListRuns(session_id);
  if (!runs.ok()) return runs.status();
  json out = json::array();
  for (const storage::Run& r : *runs) {
    if (!runs_service) {
      out.push_back(api::RunViewToJson(storage::RunViewOf(r)));
      continue;
    }
    auto view = runs_service->Get(r.id);
    if (!view.ok()) return view.status();
    out.push_back(api::RunViewToJson(*view));
  }
  return out;
}

/// POST /sessions/{id}/trials with a JSON {spec, data} body: one recording.
api::Result<services::ImportResult> ImportRecordingBody(storage::Database& db, RequestContext& ctx,
                                                        const UploadBody& upload,
                                                        services::MemoryBudget& budget,
                                                        std::int64_t session_id,
                                                        const std::string& user) {
  auto recording = services::ReadRecordingUpload(upload.fd, upload.size, budget);
  if (!recording.ok()) return recording.status();
  ctx.body = {{"spec", recording->spec_json}};
  return AuditedWrite<services::ImportResult>(
      db, ctx, 201,
      [&] {
        return services::ImportRecording(db, session_id, recording->data, recording->spec, user);
      },
      [](const services::ImportResult& r) {
        return "trial " + std::to_string(r.trials.front().id);
      });
}

/// POST /sessions/{id}/trials with a zip or tar.gz body: a session archive.
api::Result<services::ImportResult> ImportArchiveBody(storage::Database& db, RequestContext& ctx,
                                                      const UploadBody& upload,
                                                      services::ArchiveFormat format,
                                                      services::MemoryBudget& budget,
                                                      std::int64_t session_id,
                                                      const std::string& user) {
  auto archive = services::UnpackArchive(upload.fd, format, budget);
  if (!archive.ok()) return archive.status();
  const std::string name = ctx.Query("name").value_or("upload");
  ctx.body = {{"archive", name}, {"bytes", upload.size}};
  return AuditedWrite<services::ImportResult>(
      db, ctx, 201,
      [&] { return services::ImportArchive(db, session_id, archive->files, name, user); },
      [session_id](const services::ImportResult& r) {
        return "session " + std::to_string(session_id) + ": " + std::to_string(r.trials.size()) +
               " trials";
      });
}

// The import route's handler: the media type chooses the reader.
api::Result<Reply> ImportTrials(storage::Database& db, services::MemoryBudget& budget,
                                RequestContext& ctx) {
  const std::int64_t session_id = ctx.Id("session_id");
  if (auto s = storage::SessionRepository(db).Get(session_id); !s.ok()) return s.status();
  const std::string type = MediaType(ctx.req);
  const std::optional<services::ArchiveFormat> format =
      type == "application/zip"    ? std::optional(services::ArchiveFormat::kZip)
      : type == "application/gzip" ? std::optional(services::ArchiveFormat::kTarGz)
                                   : std::nullopt;
  if (type != "application/json" && !format) {
    return api::Status::InvalidArgument(
        "send a recording as application/json {spec, data} or a session archive as "
        "application/zip or application/gzip, not '" +
            type + "'",
        "Content-Type");
  }
  // The front end spools every upload to a file (http_server.h).
  if (ctx.upload == nullptr) return api::Status::Internal("the upload was not spooled");
  const UploadBody& upload = *ctx.upload;
  const std::string user = ctx.user ? ctx.user->name : std::string("anonymous");
  api::Result<services::ImportResult> imported =
      format ? ImportArchiveBody(db, ctx, upload, *format, budget, session_id, user)
             : ImportRecordingBody(db, ctx, upload, budget, session_id, user);
  if (!imported.ok()) return imported.status();
  return JsonReply(api::ImportResultToJson(*imported), 201);
}

// The trial kinds, and importing a recording or a session archive.
void AddImportRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  // One budget for every import this server runs.
  auto budget = std::make_shared<services::MemoryBudget>(kImportMemoryBytes);
  table.Add({.method = "GET",
             .path = "/api/v1/trial-kinds",
             .permission = Permission::kRead,
             .tag = "trials",
             .summary = "The trial kinds the server knows (an import declares one), with the "
                        "channels each needs",
             .handler = [](RequestContext&) -> api::Result<Reply> {
               json items = json::array();
               for (const api::TrialKindInfo& k : api::TrialKinds()) {
                 json channels = json::array({std::string(api::kTimeChannel)});
                 for (std::string_view c : k.required_channels) channels.push_back(std::string(c));
                 items.push_back({{"name", k.name},
                                  {"family", k.family},
                                  {"protocol", protocols::RecordingProtocol(k.kind)},
                                  {"description", k.description},
                                  {"required_channels", std::move(channels)},
                                  {"motor", k.motor},
                                  {"knee_locked", k.knee_locked},
                                  {"free_swing", api::IsFreeSwing(k.kind)},
                                  {"validation", api::IsValidation(k.kind)}});
               }
               return JsonReply({{"items", std::move(items)}});
             }});

  table.Add(
      {.method = "POST",
       .path = "/api/v1/sessions/{session_id}/trials",
       // Writing a session's data is a clinician's (docs/API.md, "Roles and
       // permissions"); analysts read and analyse.
       .permission = Permission::kRecord,
       .audit = Audit::kHandler,
       .tag = "trials",
       .summary =
           "Import trials into a session: one recording (CSV, TSV or OpenSim .sto, with its trial "
           "kind and column mapping) as JSON, or a whole session archive (zip or tar.gz); checked "
           "first, stored all or nothing, each trial with its import provenance",
       .query = {{"name", "string", "archive uploads: the file name, kept as provenance"}},
       .success_status = 201,
       .request_schema = ImportSchema(),
       .handler = [&db, budget](RequestContext& ctx) { return ImportTrials(db, *budget, ctx); },
       .raw_body = true});
}

// A session's report and its export as an archive.
void AddReportAndExportRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  table.Add(
      {.method = "GET",
       .path = "/api/v1/sessions/{session_id}/report",
       .permission = Permission::kRead,
       .tag = "sessions",
       .summary =
           "The session report: one self-contained, printable HTML page (subject by pseudonymous "
           "code, session values, runs and outcomes, e-stops and clamps, trials, parameter sets "
           "with "
           "their curves, predictions on fresh trials, warnings); print it to PDF from the browser",
       .produces = "text/html",
       .handler = [&db, runs_service = deps.runs,
                   version = deps.server_version](RequestContext& ctx) -> api::Result<Reply> {
         const std::int64_t session_id = ctx.Id("session_id");
         auto session = storage::SessionRepository(db).Get(session_id);
         if (!session.ok()) return session.status();
         services::SessionReport base;
         base.software_version = version;
         base.generated_at_utc = api::FormatUtc(db.Now());
         auto session_json = SessionJson(db, *session);
         if (!session_json.ok()) return session_json.status();
         base.session = std::move(*session_json);
         auto subject = storage::SubjectRepository(db).Get(session->subject_id);
         if (!subject.ok()) return subject.status();
         auto subject_json = SubjectJson(db, *subject);
         if (!subject_json.ok()) return subject_json.status();
         base.subject = std::move(*subject_json);
         auto runs = RunsJson(db, runs_service, session_id);
         if (!runs.ok()) return runs.status();
         base.runs = std::move(*runs);
         auto trials = storage::TrialRepository(db).ListForSession(session_id);
         if (!trials.ok()) return trials.status();
         base.trials = json::array();
         for (const storage::TrialSummary& t : *trials)
           base.trials.push_back(api::TrialSummaryToJson(t));
         auto report = services::GatherSessionReport(db, session_id, std::move(base));
         if (!report.ok()) return report.status();
         ctx.res.status = 200;
         ctx.res.set_content(services::RenderSessionReport(*report), "text/html; charset=utf-8");
         return Reply{200, nullptr, true};
       }});

  table.Add(
      {.method = "GET",
       .path = "/api/v1/sessions/{session_id}/export",
       .permission = Permission::kRead,
       .tag = "sessions",
       .summary =
           "The whole session as one archive laid out after BIDS (motion/EMG TSV with channels and "
           "JSON sidecars, stimulation pulses as events), with its parameter sets, run log and a "
           "README of the layout; zip (default) or tar.gz by ?format or Accept",
       .query = {{"format", "string", "zip (default) or tar.gz"}},
       .produces = "application/zip",
       .handler = [&db, runs_service = deps.runs,
                   version = deps.server_version](RequestContext& ctx) -> api::Result<Reply> {
         services::ArchiveFormat format = services::ArchiveFormat::kZip;
         if (const auto f = ctx.Query("format")) {
           const auto parsed = services::ParseArchiveFormat(*f);
           if (!parsed) return api::Status::InvalidArgument("must be zip or tar.gz", "format");
           format = *parsed;
         } else if (ctx.req.get_header_value("Accept").find("application/gzip") !=
                    std::string::npos) {
           format = services::ArchiveFormat::kTarGz;
         }
         const std::int64_t session_id = ctx.Id("session_id");
         auto session = storage::SessionRepository(db).Get(session_id);
         if (!session.ok()) return session.status();
         auto session_json = SessionJson(db, *session);
         if (!session_json.ok()) return session_json.status();
         auto subject = storage::SubjectRepository(db).Get(session->subject_id);
         if (!subject.ok()) return subject.status();
         auto subject_json = SubjectJson(db, *subject);
         if (!subject_json.ok()) return subject_json.status();
         auto runs = RunsJson(db, runs_service, session_id);
         if (!runs.ok()) return runs.status();
         auto files = services::SessionExportFiles(
             db, {session_id, *session_json, *subject_json, *runs, version});
         if (!files.ok()) return files.status();
         const std::string root = "fesbench-session-" + std::to_string(session_id);
         auto packed = services::PackArchive(*files, format, root);
         if (!packed.ok()) return packed.status();
         ctx.res.status = 200;
         ctx.res.set_header("Content-Disposition",
                            "attachment; filename=\"" + root + "." +
                                std::string(services::ArchiveFormatName(format)) + "\"");
         ctx.res.set_content(std::move(*packed), std::string(services::ArchiveMediaType(format)));
         return Reply{200, nullptr, true};
       }});
}

}  // namespace

void AddDataRoutes(RouteTable& table, const ApiDependencies& deps) {
  AddImportRoutes(table, deps);
  AddReportAndExportRoutes(table, deps);
}

}  // namespace fesbench::server::http
