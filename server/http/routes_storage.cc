// Storage-backed routes: health, subjects, sessions, trials, parameter sets,
// protocols, stored predictions (docs/API.md).

#include <cctype>
#include <functional>
#include <map>
#include <mutex>
#include <sstream>
#include <unordered_map>

#include "api/bids.h"
#include "api/trial.h"
#include "server/http/api_routes.h"
#include "server/http/resources_json.h"
#include "server/http/routes_common.h"
#include "server/protocols/protocol.h"
#include "server/services/run_service.h"
#include "storage/parameter_sets.h"
#include "storage/predictions.h"
#include "storage/sessions.h"
#include "storage/subjects.h"
#include "storage/trials.h"

namespace fesbench::server::http {

namespace {

using nlohmann::json;

// Parameter sets are immutable (docs/ARCHITECTURE.md, data path): their rendered JSON can be
// kept without ever being stale. Their approval is not part of it.
class ParameterSetCache {
 public:
  std::optional<std::string> Find(std::int64_t id) {
    std::lock_guard lock(mu_);
    auto it = bodies_.find(id);
    if (it == bodies_.end()) return std::nullopt;
    return it->second;
  }
  void Put(std::int64_t id, std::string body) {
    std::lock_guard lock(mu_);
    if (bodies_.size() >= kCapacity) bodies_.clear();
    bodies_.emplace(id, std::move(body));
  }

 private:
  static constexpr std::size_t kCapacity = 2048;
  std::mutex mu_;
  std::unordered_map<std::int64_t, std::string> bodies_;
};

// A rendered JSON object with `fields` added (the cached, immutable body of
// a set with its approval, which changes).
std::string WithFields(std::string object, const json& fields) {
  object.pop_back();  // the closing brace
  for (const auto& [key, value] : fields.items()) {
    object += "," + json(key).dump() + ":" + value.dump();
  }
  return object + "}";
}

// The newest approval of each set, by set id, read from the database once
// per change of approvals (storage::Database::approvals_version): a GET of
// a set, or of a page of them, reads no approval row while nothing was
// approved since. Only where this server is the database's one writer; on a
// PostgreSQL database that other servers share, every request reads.
class ApprovalCache {
 public:
  explicit ApprovalCache(storage::Database& db) : db_(db) {}

  api::Result<std::map<std::int64_t, storage::Approval>> Newest(
      const std::vector<std::int64_t>& ids) {
    if (!db_.only_writer()) return Read(ids);
    // The version before the read: an approval committed meanwhile moves it
    // on, so what this read found is never kept under the newer version.
    const std::uint64_t version = db_.approvals_version();
    std::map<std::int64_t, storage::Approval> out;
    std::vector<std::int64_t> missing;
    {
      std::lock_guard lock(mu_);
      if (version_ != version) {
        entries_.clear();
        version_ = version;
      }
      for (std::int64_t id : ids) {
        auto it = entries_.find(id);
        if (it == entries_.end()) {
          missing.push_back(id);
        } else if (it->second) {
          out.emplace(id, *it->second);
        }
      }
    }
    if (missing.empty()) return out;
    auto read = Read(missing);
    if (!read.ok()) return read.status();
    std::lock_guard lock(mu_);
    const bool current = version_ == version && db_.approvals_version() == version;
    if (current && entries_.size() + missing.size() > kCapacity) entries_.clear();
    for (std::int64_t id : missing) {
      auto it = read->find(id);
      std::optional<storage::Approval> found;
      if (it != read->end()) found = it->second;
      if (current) entries_[id] = found;
      if (found) out.emplace(id, std::move(*found));
    }
    return out;
  }

 private:
  api::Result<std::map<std::int64_t, storage::Approval>> Read(
      const std::vector<std::int64_t>& ids) {
    auto approvals = storage::ParameterSetRepository(db_).LatestApprovals(ids);
    if (!approvals.ok()) return approvals.status();
    std::map<std::int64_t, storage::Approval> out;
    for (storage::Approval& a : *approvals) out.emplace(a.parameter_set_id, std::move(a));
    return out;
  }

  static constexpr std::size_t kCapacity = 4096;
  storage::Database& db_;
  std::mutex mu_;
  std::uint64_t version_ = 0;
  // Set id → its newest approval, or none (never approved).
  std::unordered_map<std::int64_t, std::optional<storage::Approval>> entries_;
};

// The newest approval of each listed set, by set id.
api::Result<std::map<std::int64_t, storage::Approval>> NewestApprovals(
    ApprovalCache& approvals, const std::vector<storage::ParameterSetSummary>& sets) {
  std::vector<std::int64_t> ids;
  for (const storage::ParameterSetSummary& s : sets) ids.push_back(s.id);
  return approvals.Newest(ids);
}

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

// A correction (PATCH) in one write transaction with its audit entry,
// whose summary carries the reason and the changed values in full.
api::Result<json> AuditedCorrection(storage::Database& db, RequestContext& ctx,
                                    const std::string& target, const std::string& reason,
                                    const std::vector<std::string>& changed,
                                    const json& new_details,
                                    const std::function<api::Result<json>()>& write) {
  std::string summary = "reason: " + reason + "; changed:";
  for (const std::string& key : changed) {
    summary += " " + key + "=" + (new_details.contains(key) ? new_details.at(key).dump() : "null");
  }
  auto result = db.Write([&](storage::Connection&) -> api::Result<json> {
    api::Result<json> value = write();
    if (!value.ok()) return value;
    auto appended = storage::AuditLog(db).Append(
        {ctx.user ? std::optional<std::int64_t>(ctx.user->id) : std::nullopt,
         ctx.user ? ctx.user->name : std::string("anonymous"), ctx.req.method + " " + ctx.req.path,
         target, summary, "200"});
    if (!appended.ok()) return appended.status();
    return value;
  });
  if (result.ok()) ctx.audited = true;
  return result;
}

// The revision number each revision corrects (ids → numbers).
template <typename Revision>
json RevisionsJson(const std::vector<Revision>& revisions,
                   json (*to_json)(const Revision&, std::optional<int>)) {
  json items = json::array();
  for (const Revision& r : revisions) {
    std::optional<int> corrects;
    for (const Revision& other : revisions) {
      if (r.corrects_id && other.id == *r.corrects_id) corrects = other.revision;
    }
    items.push_back(to_json(r, corrects));
  }
  return {{"items", std::move(items)}};
}

json CorrectionSchema(json details) {
  return ObjectSchema({{"reason", {{"type", "string"}, {"minLength", 1}, {"maxLength", 500}}},
                       {"details", std::move(details)}},
                      {"reason", "details"});
}

// GET /health: liveness, version, schema version.
void AddHealthRoute(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  const std::string version = deps.server_version;
  table.Add({.method = "GET",
             .path = "/api/v1/health",
             .roles = 0,
             .tag = "system",
             .summary = "Liveness and database health",
             .handler = [&db, version](RequestContext&) -> api::Result<Reply> {
               auto schema = db.SchemaVersion();
               if (!schema.ok()) return schema.status();
               return JsonReply({{"status", "ok"},
                                 {"version", version},
                                 {"schema_version", *schema},
                                 {"time_utc", storage::FormatUtc(db.Now())}});
             }});
}

// Subjects: list, create, get, correct, revisions.
void AddSubjectRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  {
    auto q = PageParams();
    q.push_back({"code", "string", "exact pseudonymous code"});
    table.Add({.method = "GET",
               .path = "/api/v1/subjects",
               .roles = kAnyRole,
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
             .roles = kClinician | kAdmin,
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
             .roles = kAnyRole,
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
       .roles = kClinician | kAdmin,
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
             SubjectDetailsToJson(correction->details), [&]() -> api::Result<json> {
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
             .roles = kAnyRole,
             .tag = "subjects",
             .summary = "A subject's revisions, oldest first (who, when, why, the details)",
             .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
               auto revisions = storage::SubjectRepository(db).Revisions(ctx.Id("subject_id"));
               if (!revisions.ok()) return revisions.status();
               return JsonReply(RevisionsJson(*revisions, &SubjectRevisionToJson));
             }});
}

// Sessions: a subject's list, and a new one.
void AddSessionRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  {
    auto q = PageParams();
    q.push_back({"from", "string", "sessions on or after this date (YYYY-MM-DD)"});
    q.push_back({"to", "string", "sessions before this date (YYYY-MM-DD)"});
    table.Add({.method = "GET",
               .path = "/api/v1/subjects/{subject_id}/sessions",
               .roles = kAnyRole,
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
                   if (*from && date < storage::FormatUtc(**from).substr(0, 10)) continue;
                   if (*to && date >= storage::FormatUtc(**to).substr(0, 10)) continue;
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
             .roles = kClinician | kAdmin,
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
                     return SessionToJson(*session, storage::SideName(request->leg));
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
             .roles = kAnyRole,
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
       .roles = kClinician | kAdmin,
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
         storage::Session preview = *current;
         preview.current.details = correction->details;
         auto corrected = AuditedCorrection(
             db, ctx, "sessions/" + std::to_string(id), correction->reason, correction->changed,
             SessionToJson(preview, "").at("details"), [&]() -> api::Result<json> {
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
             .roles = kAnyRole,
             .tag = "sessions",
             .summary = "A session's revisions, oldest first (who, when, why, the details)",
             .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
               auto revisions = storage::SessionRepository(db).Revisions(ctx.Id("session_id"));
               if (!revisions.ok()) return revisions.status();
               return JsonReply(RevisionsJson(*revisions, &SessionRevisionToJson));
             }});
}

// A session's runs and trials, paged.
void AddSessionRunAndTrialRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  table.Add(
      {.method = "GET",
       .path = "/api/v1/sessions/{session_id}/runs",
       .roles = kAnyRole,
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
             .roles = kAnyRole,
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
                   TrialSummaryToJson));
             }});
}

// Trials: get, and export as CSV or OpenSim .sto.
void AddTrialRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  table.Add(
      {.method = "GET",
       .path = "/api/v1/trials/{trial_id}",
       .roles = kAnyRole,
       .tag = "trials",
       .summary =
           "A recorded trial: JSON, CSV or OpenSim .sto (?format=json|csv|sto, or Accept: "
           "text/csv); a download with a Content-Disposition file name when ?format is given. CSV "
           "and .sto hold one channel group (?group=main, the default, or emg); the .sto header "
           "names the trial, session, subject (pseudonymous code), leg and start time; the main "
           "group's knee is OpenSim's knee_angle_r or knee_angle_l (flexion negative)",
       .query = {{"format", "string", "json (default), csv or sto"},
                 {"group", "string", "csv and sto: main (default) or emg"}},
       .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
         const std::optional<std::string> format = ctx.Query("format");
         if (format && *format != "json" && *format != "csv" && *format != "sto") {
           return api::Status::InvalidArgument("must be json, csv or sto", "format");
         }
         const std::string group = ctx.Query("group").value_or("main");
         if (group != "main" && group != "emg") {
           return api::Status::InvalidArgument("must be main or emg", "group");
         }
         auto trial = storage::TrialRepository(db).Get(ctx.Id("trial_id"));
         if (!trial.ok()) return trial.status();
         if (group == "emg" && !trial->emg) {
           return api::Status::InvalidArgument(
               "trial " + std::to_string(*trial->id) + " has no EMG group", "group");
         }
         const std::string accept = ctx.req.get_header_value("Accept");
         const std::string kind =
             format ? *format : (accept.find("text/csv") != std::string::npos ? "csv" : "json");
         if (format) {
           // trial-12-rapid_free_swing_passive.csv: safe characters only.
           std::string name = trial->name.value_or("trial");
           for (char& c : name) {
             if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '-') c = '_';
           }
           if (group == "emg") name += "-emg";
           ctx.res.set_header("Content-Disposition", "attachment; filename=\"trial-" +
                                                         std::to_string(ctx.Id("trial_id")) + "-" +
                                                         name + "." + kind + "\"");
         }
         if (kind == "json") {
           json body = api::TrialToJson(*trial);
           // An imported trial says where it came from.
           auto import = storage::TrialRepository(db).ImportOf(*trial->id);
           if (!import.ok()) return import.status();
           if (*import) {
             const storage::TrialImport& i = **import;
             json spec = json::parse(i.spec_json, nullptr, false);
             body["import"] = {{"format", i.format},
                               {"source", i.source},
                               {"spec", spec.is_discarded() ? json(nullptr) : spec},
                               {"imported_by", i.imported_by},
                               {"original_trial_id",
                                i.original_trial_id ? json(*i.original_trial_id) : json(nullptr)}};
           }
           if (!format) return JsonReply(std::move(body));
           ctx.res.status = 200;
           ctx.res.set_content(body.dump(), "application/json");
           return Reply{200, nullptr, true};
         }
         const api::ChannelGroup channels = group == "emg" ? *trial->emg : trial->MainGroup();
         ctx.res.status = 200;
         if (kind == "csv") {
           ctx.res.set_content(api::GroupToCsv(channels), "text/csv");
           return Reply{200, nullptr, true};
         }
         // .sto: where the trial comes from, as header lines.
         std::vector<std::pair<std::string, std::string>> metadata = {
             {"fesbench_trial_id", std::to_string(*trial->id)}};
         auto owner = storage::TrialRepository(db).Owner(*trial->id);
         if (!owner.ok()) return owner.status();
         auto session = storage::SessionRepository(db).Get(owner->session_id);
         if (!session.ok()) return session.status();
         storage::SubjectRepository subjects(db);
         auto subject = subjects.Get(session->subject_id);
         if (!subject.ok()) return subject.status();
         auto leg = subjects.GetLeg(session->leg_id);
         if (!leg.ok()) return leg.status();
         metadata.push_back({"fesbench_session_id", std::to_string(owner->session_id)});
         metadata.push_back({"fesbench_subject", subject->code});
         metadata.push_back({"fesbench_leg", std::string(storage::SideName(leg->side))});
         if (trial->start_time_unix_ms) {
           metadata.push_back({"fesbench_start_time_utc",
                               storage::FormatUtc(storage::UtcTime(
                                   std::chrono::milliseconds(*trial->start_time_unix_ms)))});
         }
         std::ostringstream rate;
         rate << channels.sample_rate_hz;
         metadata.push_back({"fesbench_sample_rate_hz", rate.str()});
         // The knee as OpenSim's coordinate (docs/API.md "Session archives").
         ctx.res.set_content(
             api::GroupToSto(group == "main"
                                 ? api::ToOpenSimCoordinates(channels, storage::SideName(leg->side))
                                 : channels,
                             trial->name.value_or("fesbench_trial"), metadata),
             "text/plain");
         return Reply{200, nullptr, true};
       }});
}

// Parameter sets: history, get (cached JSON), predictions, export.
void AddParameterSetRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  auto cache = std::make_shared<ParameterSetCache>();
  auto approval_cache = std::make_shared<ApprovalCache>(db);
  {
    auto q = PageParams();
    q.push_back({"subject_id", "integer", "only this subject's sets"});
    q.push_back({"leg", "string", "left or right (with subject_id)"});
    q.push_back({"method", "string", "IRC, passive or active identification method"});
    q.push_back({"from", "string", "created at or after (YYYY-MM-DD or UTC time)"});
    q.push_back({"to", "string", "created before (YYYY-MM-DD or UTC time)"});
    table.Add({.method = "GET",
               .path = "/api/v1/parameter-sets",
               .roles = kAnyRole,
               .tag = "parameter-sets",
               .summary = "Parameter-set history (filter by subject, leg, method, date range)",
               .query = q,
               .handler = [&db, approval_cache](RequestContext& ctx) -> api::Result<Reply> {
                 auto page = ParsePage(ctx);
                 if (!page.ok()) return page.status();
                 auto subject_id = QueryId(ctx, "subject_id");
                 if (!subject_id.ok()) return subject_id.status();
                 auto from = QueryTime(ctx, "from");
                 if (!from.ok()) return from.status();
                 auto to = QueryTime(ctx, "to");
                 if (!to.ok()) return to.status();
                 std::optional<storage::Side> side;
                 if (auto leg = ctx.Query("leg")) {
                   side = storage::ParseSide(*leg);
                   if (!side) return api::Status::InvalidArgument("must be left or right", "leg");
                   if (!*subject_id) {
                     return api::Status::InvalidArgument("a leg filter needs subject_id", "leg");
                   }
                 }
                 auto method = ctx.Query("method");
                 if (method && (method->empty() || method->size() > 64)) {
                   return api::Status::InvalidArgument("must be 1–64 characters", "method");
                 }
                 storage::ParameterSetListQuery query;
                 query.subject_id = *subject_id;
                 query.method = method;
                 query.from = *from;
                 query.to = *to;
                 query.after_id = page->after_id;
                 query.limit = page->limit + 1;  // the extra row: a next page exists
                 if (side) {
                   auto legs = storage::SubjectRepository(db).Legs(**subject_id);
                   if (!legs.ok()) return legs.status();
                   query.leg_id = -1;  // a leg the subject lacks matches nothing
                   for (const auto& leg : *legs) {
                     if (leg.side == *side) query.leg_id = leg.id;
                   }
                 }
                 auto found = storage::ParameterSetRepository(db).List(query);
                 if (!found.ok()) return found.status();
                 auto approvals = NewestApprovals(*approval_cache, *found);
                 if (!approvals.ok()) return approvals.status();
                 return JsonReply(MakePage(
                     *found, *page, [](const storage::ParameterSetSummary& s) { return s.id; },
                     [&](const storage::ParameterSetSummary& s) {
                       json j = ParameterSetSummaryToJson(s);
                       const auto it = approvals->find(s.id);
                       j.update(ApprovalFieldsToJson(
                           it == approvals->end() ? std::nullopt
                                                  : std::optional<storage::Approval>(it->second)));
                       return j;
                     }));
               }});
  }
  table.Add({.method = "GET",
             .path = "/api/v1/parameter-sets/{parameter_set_id}",
             .roles = kAnyRole,
             .tag = "parameter-sets",
             .summary = "One parameter set (docs/MODEL.md JSON) with its provenance",
             .handler = [&db, cache, approval_cache](RequestContext& ctx) -> api::Result<Reply> {
               const std::int64_t id = ctx.Id("parameter_set_id");
               auto body = cache->Find(id);
               if (!body) {
                 auto set = storage::ParameterSetRepository(db).Get(id);
                 if (!set.ok()) return set.status();
                 body = StoredParameterSetToJson(*set).dump();
                 cache->Put(id, *body);
               }
               auto approval = approval_cache->Newest({id});
               if (!approval.ok()) return approval.status();
               const auto it = approval->find(id);
               ctx.res.status = 200;
               ctx.res.set_content(
                   WithFields(std::move(*body),
                              ApprovalFieldsToJson(it == approval->end()
                                                       ? std::nullopt
                                                       : std::optional(it->second))),
                   "application/json");
               return Reply{200, nullptr, true};
             }});
  table.Add({.method = "GET",
             .path = "/api/v1/parameter-sets/{parameter_set_id}/predictions",
             .roles = kAnyRole,
             .tag = "predictions",
             .summary = "Stored predictions of a parameter set",
             .query = PageParams(),
             .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
               auto page = ParsePage(ctx);
               if (!page.ok()) return page.status();
               const std::int64_t id = ctx.Id("parameter_set_id");
               if (auto set = storage::ParameterSetRepository(db).Get(id); !set.ok()) {
                 return set.status();
               }
               auto predictions = storage::PredictionRepository(db).PredictionsFor(id);
               if (!predictions.ok()) return predictions.status();
               return JsonReply(MakePage(
                   *predictions, *page, [](const storage::Prediction& p) { return p.id; },
                   [](const storage::Prediction& p) {
                     return json{{"id", p.id},
                                 {"parameter_set_id", p.prediction.parameter_set_id},
                                 {"trial_id", p.prediction.trial_id ? json(*p.prediction.trial_id)
                                                                    : json(nullptr)},
                                 {"created_at_utc", storage::FormatUtc(p.created_at)}};
                   }));
             }});
  table.Add({.method = "GET",
             .path = "/api/v1/predictions/{prediction_id}",
             .roles = kAnyRole,
             .tag = "predictions",
             .summary = "A stored prediction with its input and output",
             .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
               auto p = storage::PredictionRepository(db).GetPrediction(ctx.Id("prediction_id"));
               if (!p.ok()) return p.status();
               auto parse = [](const std::string& text) {
                 json j = json::parse(text, nullptr, false);
                 return j.is_discarded() ? json(nullptr) : j;
               };
               return JsonReply({{"id", p->id},
                                 {"parameter_set_id", p->prediction.parameter_set_id},
                                 {"trial_id", p->prediction.trial_id ? json(*p->prediction.trial_id)
                                                                     : json(nullptr)},
                                 {"input", parse(p->prediction.input_json)},
                                 {"output", parse(p->prediction.output_json)},
                                 {"created_at_utc", storage::FormatUtc(p->created_at)}});
             }});
}

// Protocols: the catalog and one protocol, with defaults resolved from a session.
void AddProtocolRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  // ?session_id=N resolves the defaults derived from the session.
  const auto session_context =
      [&db, runs = deps.runs](
          RequestContext& ctx) -> api::Result<std::optional<services::SessionContext>> {
    auto id = QueryId(ctx, "session_id");
    if (!id.ok()) return id.status();
    if (!*id) return std::optional<services::SessionContext>();
    auto context =
        services::LoadSessionContext(db, **id, runs ? runs->bench().limits() : BenchLimits{});
    if (!context.ok()) return context.status();
    return std::optional<services::SessionContext>(std::move(*context));
  };
  const std::vector<QueryParam> protocol_query = {
      {"session_id", "integer",
       "resolve the defaults derived from this session (threshold, max tolerated, range)"}};
  table.Add({.method = "GET",
             .path = "/api/v1/protocols",
             .roles = kAnyRole,
             .tag = "protocols",
             .summary =
                 "The protocol catalog (docs/PROTOCOLS.md): labels, units, defaults (resolved with "
                 "?session_id), thesis sections",
             .query = protocol_query,
             .handler = [session_context](RequestContext& ctx) -> api::Result<Reply> {
               auto context = session_context(ctx);
               if (!context.ok()) return context.status();
               if (!*context) return JsonReply(protocols::CatalogToJson());
               return JsonReply(protocols::CatalogToJson(&(*context)->subject,
                                                         (*context)->has_stimulation_limits));
             }});
  table.Add({.method = "GET",
             .path = "/api/v1/protocols/{name}",
             .roles = kAnyRole,
             .tag = "protocols",
             .summary = "One protocol with its parameters, labels, units and defaults",
             .query = protocol_query,
             .handler = [session_context](RequestContext& ctx) -> api::Result<Reply> {
               const auto* protocol = protocols::FindProtocol(ctx.path.at("name"));
               if (!protocol) {
                 return api::Status::NotFound("protocol " + ctx.path.at("name") + " not found");
               }
               auto context = session_context(ctx);
               if (!context.ok()) return context.status();
               if (!*context) return JsonReply(protocols::ProtocolToJson(*protocol));
               return JsonReply(protocols::ProtocolToJson(*protocol, &(*context)->subject,
                                                          (*context)->has_stimulation_limits));
             }});
}

}  // namespace

void AddStorageRoutes(RouteTable& table, const ApiDependencies& deps) {
  AddHealthRoute(table, deps);
  AddSubjectRoutes(table, deps);
  AddSessionRoutes(table, deps);
  AddSessionRecordRoutes(table, deps);
  AddSessionRunAndTrialRoutes(table, deps);
  AddTrialRoutes(table, deps);
  AddParameterSetRoutes(table, deps);
  AddProtocolRoutes(table, deps);
}

}  // namespace fesbench::server::http
