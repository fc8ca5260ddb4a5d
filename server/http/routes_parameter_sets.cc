// Parameter sets: a leg's history, one set (cached JSON), its stored
// predictions, export (docs/API.md).

#include <map>
#include <mutex>
#include <unordered_map>

#include "server/http/api_routes.h"
#include "server/http/resources_json.h"
#include "server/http/routes_common.h"
#include "storage/parameter_sets.h"
#include "storage/predictions.h"

namespace fesbench::server::http {

using nlohmann::json;

namespace {

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

}  // namespace

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
               .permission = Permission::kRead,
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
                       api::ParameterSetSummary summary = storage::ParameterSetResource(s);
                       const auto it = approvals->find(s.id);
                       summary.approval = storage::ApprovalResource(
                           it == approvals->end() ? std::nullopt
                                                  : std::optional<storage::Approval>(it->second));
                       return api::ParameterSetSummaryToJson(summary);
                     }));
               }});
  }
  table.Add({.method = "GET",
             .path = "/api/v1/parameter-sets/{parameter_set_id}",
             .permission = Permission::kRead,
             .tag = "parameter-sets",
             .summary = "One parameter set (docs/MODEL.md JSON) with its provenance",
             .handler = [&db, cache, approval_cache](RequestContext& ctx) -> api::Result<Reply> {
               const std::int64_t id = ctx.Id("parameter_set_id");
               auto body = cache->Find(id);
               if (!body) {
                 auto set = storage::ParameterSetRepository(db).Get(id);
                 if (!set.ok()) return set.status();
                 body = api::StoredParameterSetToJson(ParameterSetResourceWithNotes(*set)).dump();
                 cache->Put(id, *body);
               }
               auto approval = approval_cache->Newest({id});
               if (!approval.ok()) return approval.status();
               const auto it = approval->find(id);
               ctx.res.status = 200;
               ctx.res.set_content(
                   WithFields(std::move(*body), api::ApprovalStateToJson(storage::ApprovalResource(
                                                    it == approval->end()
                                                        ? std::nullopt
                                                        : std::optional(it->second)))),
                   "application/json");
               return Reply{200, nullptr, true};
             }});
  table.Add({.method = "GET",
             .path = "/api/v1/parameter-sets/{parameter_set_id}/predictions",
             .permission = Permission::kRead,
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
                                 {"created_at_utc", api::FormatUtc(p.created_at)}};
                   }));
             }});
  table.Add({.method = "GET",
             .path = "/api/v1/predictions/{prediction_id}",
             .permission = Permission::kRead,
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
                                 {"created_at_utc", api::FormatUtc(p->created_at)}});
             }});
}

}  // namespace fesbench::server::http
