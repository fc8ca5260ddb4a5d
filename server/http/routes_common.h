#pragma once

/// @file
/// Helpers shared by the route files (internal to server/http): paging,
/// query-parameter parsing, audited storage writes.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "api/status.h"
#include "server/http/http_server.h"
#include "server/http/router.h"
#include "storage/audit_log.h"
#include "storage/database.h"
#include "storage/sessions.h"
#include "storage/subjects.h"
#include "api/time_utc.h"

namespace fesbench::server::http {

inline constexpr std::size_t kDefaultPageLimit = 50;
inline constexpr std::size_t kMaxPageLimit = 500;

/// ?limit (1–500, default 50) and ?cursor (opaque, from a previous page's
/// next_cursor): the page starts after the cursor's id.
struct PageRequest {
  std::size_t limit = kDefaultPageLimit;
  std::int64_t after_id = 0;
};

/// The paging query parameters, for Route::query.
std::vector<QueryParam> PageParams();
api::Result<PageRequest> ParsePage(const RequestContext& ctx);
/// The opaque cursor for "after id".
std::string EncodeCursor(std::int64_t after_id);
std::optional<std::int64_t> DecodeCursor(std::string_view cursor);

/// {"items": [...], "next_cursor": "..." | null} of `items` (ascending by
/// id): those with id > after_id, at most limit.
template <typename T, typename IdOf, typename ToJson>
nlohmann::json MakePage(const std::vector<T>& items, const PageRequest& page, IdOf id_of,
                        ToJson to_json) {
  nlohmann::json out = nlohmann::json::array();
  auto it = std::find_if(items.begin(), items.end(),
                         [&](const T& item) { return id_of(item) > page.after_id; });
  std::int64_t last = 0;
  for (; it != items.end() && out.size() < page.limit; ++it) {
    out.push_back(to_json(*it));
    last = id_of(*it);
  }
  nlohmann::json next = it != items.end() ? nlohmann::json(EncodeCursor(last)) : nlohmann::json(nullptr);
  return {{"items", std::move(out)}, {"next_cursor", std::move(next)}};
}

/// An optional integer query parameter ≥ 1 (kInvalidArgument naming it).
api::Result<std::optional<std::int64_t>> QueryId(const RequestContext& ctx, const std::string& name);
/// An optional time bound: "YYYY-MM-DD" (midnight UTC) or a full UTC stamp.
api::Result<std::optional<api::UtcTime>> QueryTime(const RequestContext& ctx,
                                                       const std::string& name);

/// Runs `fn` (returning api::Result<T>) in one write transaction and, when it
/// succeeds, appends the audit entry of this request (target from
/// `target_of(value)`, outcome `success_status`) in the same transaction.
/// For routes with Audit::kHandler.
template <typename T, typename Fn, typename TargetOf>
api::Result<T> AuditedWrite(storage::Database& db, RequestContext& ctx, int success_status,
                            Fn&& fn, TargetOf&& target_of) {
  auto result = db.Write([&](storage::Connection&) -> api::Result<T> {
    api::Result<T> value = fn();
    if (!value.ok()) return value;
    storage::AuditLog log(db);
    auto appended = log.Append({ctx.user ? std::optional<std::int64_t>(ctx.user->id) : std::nullopt,
                                ctx.user ? ctx.user->name : std::string("anonymous"),
                                ctx.req.method + " " + ctx.req.path, target_of(*value),
                                AuditSummary(ctx.body), std::to_string(success_status)});
    if (!appended.ok()) return appended.status();
    return value;
  });
  return result;
}

/// A JSON reply.
inline Reply JsonReply(nlohmann::json body, int status = 200) {
  return Reply{status, std::move(body), false};
}

/// 503 for a service this server was built without.
inline api::Status NotAvailable(std::string_view what) {
  return api::Status::Unavailable(std::string(what) + " is not available on this server");
}

/// A stored subject with its legs, and a session with its leg's side, in
/// their resource shapes (api/subject.h, api/session.h).
api::Result<nlohmann::json> SubjectJson(storage::Database& db, const storage::Subject& subject);
api::Result<nlohmann::json> SessionJson(storage::Database& db, const storage::Session& session);

/// JSON Schema helpers for Route::request_schema.
nlohmann::json ObjectSchema(nlohmann::json properties, std::vector<std::string> required);

/// A correction (PATCH of a subject or session) in one write transaction
/// with its audit entry, whose summary carries the reason and the changed
/// values in full.
api::Result<nlohmann::json> AuditedCorrection(
    storage::Database& db, RequestContext& ctx, const std::string& target,
    const std::string& reason, const std::vector<std::string>& changed,
    const nlohmann::json& new_details, const std::function<api::Result<nlohmann::json>()>& write);

/// A correction's request schema: a reason and the corrected `details`.
nlohmann::json CorrectionSchema(nlohmann::json details);

/// Revisions (storage::RevisionResources) as {"items": [...]}.
template <typename Revision>
nlohmann::json RevisionsJson(const std::vector<Revision>& revisions,
                             nlohmann::json (*to_json)(const Revision&)) {
  nlohmann::json items = nlohmann::json::array();
  for (const Revision& r : revisions) items.push_back(to_json(r));
  return {{"items", std::move(items)}};
}

}  // namespace fesbench::server::http
