// Trials: get, and export as CSV or OpenSim .sto (docs/API.md).

#include <cctype>
#include <sstream>

#include "api/bids.h"
#include "api/trial.h"
#include "server/http/api_routes.h"
#include "api/trial_summary.h"
#include "server/http/resources_json.h"
#include "server/http/routes_common.h"
#include "storage/trials.h"

namespace fesbench::server::http {

using nlohmann::json;

// Trials: get, and export as CSV or OpenSim .sto.
void AddTrialRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  table.Add(
      {.method = "GET",
       .path = "/api/v1/trials/{trial_id}",
       .permission = Permission::kRead,
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
             body["import"] = api::TrialImportRecordToJson(
                 {i.format, i.source, spec.is_discarded() ? json(nullptr) : spec, i.imported_by,
                  i.original_trial_id});
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
                               api::FormatUtc(api::UtcTime(
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

}  // namespace fesbench::server::http
