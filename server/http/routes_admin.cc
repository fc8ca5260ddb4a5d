// Admin routes: users, tokens, audit log, backup (docs/API.md).

#include <chrono>
#include <filesystem>

#include "server/http/api_routes.h"
#include "api/json_fields.h"
#include "server/http/resources_json.h"
#include "server/http/routes_common.h"
#include "storage/audit_log.h"
#include "storage/private_files.h"
#include "storage/users.h"

namespace fesbench::server::http {

namespace {

using nlohmann::json;


// storage::UserRepository has no token listing; read the tokens table
// (metadata only: the digests never leave the database).
api::Result<std::vector<api::TokenInfo>> ListTokens(storage::Database& db) {
  return db.Read([](storage::Connection& c) -> api::Result<std::vector<api::TokenInfo>> {
    auto statement = c.Prepare(
        "SELECT t.id, t.user_id, u.name, t.label, t.created_at_utc, t.expires_at_utc, r.at_utc "
        "FROM tokens t JOIN users u ON u.id = t.user_id "
        "LEFT JOIN token_revocations r ON r.token_id = t.id ORDER BY t.id");
    if (!statement.ok()) return statement.status();
    std::vector<api::TokenInfo> rows;
    while (true) {
      auto more = statement->Step();
      if (!more.ok()) return more.status();
      if (!*more) break;
      api::TokenInfo row;
      row.id = statement->Int64(0);
      row.user_id = statement->Int64(1);
      row.user_name = statement->Text(2);
      row.label = statement->Text(3);
      row.created_at_utc = statement->Text(4);
      if (!statement->IsNull(5)) row.expires_at_utc = statement->Text(5);
      if (!statement->IsNull(6)) row.revoked_at_utc = statement->Text(6);
      rows.push_back(std::move(row));
    }
    return rows;
  });
}


// Users: list, create, deactivate.
void AddUserRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  Authenticator& auth = *deps.auth;
  table.Add({.method = "GET",
             .path = "/api/v1/users",
             .permission = Permission::kAdminister,
             .tag = "users",
             .summary = "List users",
             .query = PageParams(),
             .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
               auto page = ParsePage(ctx);
               if (!page.ok()) return page.status();
               auto users = storage::UserRepository(db).ListUsers();
               if (!users.ok()) return users.status();
               return JsonReply(MakePage(
                   *users, *page, [](const storage::User& u) { return u.id; }, api::UserToJson));
             }});
  table.Add(
      {.method = "POST",
       .path = "/api/v1/users",
       .permission = Permission::kAdminister,
       .audit = Audit::kHandler,
       .json_body = true,
       .tag = "users",
       .summary = "Create a user with a role",
       .success_status = 201,
       .request_schema =
           ObjectSchema({{"name", {{"type", "string"}, {"minLength", 1}, {"maxLength", 64}}},
                         {"role", {{"enum", {"clinician", "analyst", "admin"}}}}},
                        {"name", "role"}),
       .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
         auto request = NewUserFromJson(ctx.body);
         if (!request.ok()) return request.status();
         auto user = AuditedWrite<storage::User>(
             db, ctx, 201,
             [&] { return storage::UserRepository(db).CreateUser(request->name, request->role); },
             [](const storage::User& u) { return "users/" + std::to_string(u.id); });
         if (!user.ok()) return user.status();
         return JsonReply(api::UserToJson(*user), 201);
       }});
  table.Add(
      {.method = "POST",
       .path = "/api/v1/users/{user_id}/deactivate",
       .permission = Permission::kAdminister,
       .audit = Audit::kHandler,
       .json_body = true,
       .tag = "users",
       .summary = "Deactivate a user (their tokens stop working)",
       .request_schema = ObjectSchema(
           {{"reason", {{"type", "string"}, {"minLength", 1}, {"maxLength", 512}}}}, {"reason"}),
       .handler = [&db, &auth](RequestContext& ctx) -> api::Result<Reply> {
         api::JsonFields f(ctx.body);
         auto reason = f.String("reason", true, 512);
         if (auto st = f.Finish(); !st.ok()) return st;
         if (reason->empty()) return api::Status::InvalidArgument("must not be empty", "reason");
         const std::int64_t user_id = ctx.Id("user_id");
         if (ctx.user && ctx.user->id == user_id) {
           return api::Status::FailedPrecondition("an admin cannot deactivate themself");
         }
         auto user = AuditedWrite<storage::User>(
             db, ctx, 200,
             [&]() -> api::Result<storage::User> {
               storage::UserRepository users(db);
               if (auto st = users.DeactivateUser(user_id, *reason); !st.ok()) return st;
               return users.GetUser(user_id);
             },
             [](const storage::User& u) { return "users/" + std::to_string(u.id); });
         if (!user.ok()) return user.status();
         auth.Invalidate();
         return JsonReply(api::UserToJson(*user));
       }});
}

// Tokens: list, create (shown once), revoke.
void AddTokenRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  Authenticator& auth = *deps.auth;
  table.Add({.method = "GET",
             .path = "/api/v1/tokens",
             .permission = Permission::kAdminister,
             .tag = "tokens",
             .summary = "List tokens (metadata; secrets are never shown again)",
             .query = PageParams(),
             .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
               auto page = ParsePage(ctx);
               if (!page.ok()) return page.status();
               auto tokens = ListTokens(db);
               if (!tokens.ok()) return tokens.status();
               return JsonReply(MakePage(
                   *tokens, *page, [](const api::TokenInfo& t) { return t.id; }, api::TokenInfoToJson));
             }});
  table.Add(
      {.method = "POST",
       .path = "/api/v1/tokens",
       .permission = Permission::kAdminister,
       .audit = Audit::kHandler,
       .json_body = true,
       .tag = "tokens",
       .summary = "Issue a bearer token for a user (the secret is in this response only)",
       .success_status = 201,
       .request_schema = ObjectSchema({{"user_id", {{"type", "integer"}, {"minimum", 1}}},
                                       {"label", {{"type", "string"}, {"maxLength", 128}}},
                                       {"expires_in_s", {{"type", "integer"}, {"minimum", 60}}}},
                                      {"user_id"}),
       .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
         auto request = NewTokenFromJson(ctx.body);
         if (!request.ok()) return request.status();
         std::optional<api::UtcTime> expires;
         if (request->expires_in_s) {
           expires = db.Now() + std::chrono::seconds(*request->expires_in_s);
         }
         auto issued = AuditedWrite<storage::IssuedToken>(
             db, ctx, 201,
             [&] {
               return storage::UserRepository(db).IssueToken(request->user_id, request->label,
                                                             expires);
             },
             [](const storage::IssuedToken& t) { return "tokens/" + std::to_string(t.token_id); });
         if (!issued.ok()) {
           if (issued.status().code() == api::ErrorCode::kNotFound) {
             return api::Status(api::ErrorCode::kNotFound, issued.status().message(), "user_id");
           }
           return issued.status();
         }
         return JsonReply(api::IssuedTokenToJson({issued->token_id, request->user_id,
                                                  request->label, issued->token,
                                                  issued->expires_at}),
                          201);
       }});
  table.Add({.method = "DELETE",
             .path = "/api/v1/tokens/{token_id}",
             .permission = Permission::kAdminister,
             .audit = Audit::kHandler,
             .tag = "tokens",
             .summary = "Revoke a token",
             .handler = [&db, &auth](RequestContext& ctx) -> api::Result<Reply> {
               const std::int64_t id = ctx.Id("token_id");
               auto revoked = AuditedWrite<json>(
                   db, ctx, 200,
                   [&]() -> api::Result<json> {
                     if (auto st = storage::UserRepository(db).RevokeToken(id); !st.ok()) return st;
                     return json{{"id", id}, {"revoked", true}};
                   },
                   [id](const json&) { return "tokens/" + std::to_string(id); });
               if (!revoked.ok()) return revoked.status();
               auth.Invalidate();
               return JsonReply(std::move(*revoked));
             }});
}

// The audit log, and the online backup.
void AddAuditAndBackupRoutes(RouteTable& table, const ApiDependencies& deps) {
  storage::Database& db = *deps.db;
  const std::string backup_dir = deps.backup_dir;
  {
    std::vector<QueryParam> q = {{"limit", "integer", "page size, 1–500 (default 50)"},
                                 {"cursor", "string", "opaque cursor from next_cursor"},
                                 {"user_id", "integer", "only this user's requests"},
                                 {"from", "string", "at or after (YYYY-MM-DD or UTC time)"},
                                 {"to", "string", "before (YYYY-MM-DD or UTC time)"}};
    table.Add({.method = "GET",
               .path = "/api/v1/audit",
               .permission = Permission::kAdminister,
               .tag = "audit",
               .summary = "The audit log of state-changing requests, newest first",
               .query = q,
               .handler = [&db](RequestContext& ctx) -> api::Result<Reply> {
                 auto page = ParsePage(ctx);
                 if (!page.ok()) return page.status();
                 storage::AuditQuery query;
                 auto user_id = QueryId(ctx, "user_id");
                 if (!user_id.ok()) return user_id.status();
                 query.user_id = *user_id;
                 auto from = QueryTime(ctx, "from");
                 if (!from.ok()) return from.status();
                 auto to = QueryTime(ctx, "to");
                 if (!to.ok()) return to.status();
                 query.from = *from;
                 query.to = *to;
                 // Newest first, paged in SQL: the cursor is the last id
                 // shown; the next page holds older (smaller) ids. One row
                 // more than the page says whether there is a next one.
                 if (page->after_id != 0) query.before_id = page->after_id;
                 query.limit = page->limit + 1;
                 auto entries = storage::AuditLog(db).List(query);
                 if (!entries.ok()) return entries.status();
                 json items = json::array();
                 std::int64_t last = 0;
                 for (std::size_t i = 0; i < entries->size() && i < page->limit; ++i) {
                   items.push_back(api::AuditEntryToJson((*entries)[i]));
                   last = (*entries)[i].id;
                 }
                 const bool more = entries->size() > page->limit;
                 return JsonReply(
                     {{"items", std::move(items)},
                      {"next_cursor", more ? json(EncodeCursor(last)) : json(nullptr)}});
               }});
  }

  table.Add({.method = "POST",
             .path = "/api/v1/backup",
             .permission = Permission::kAdminister,
             .audit = Audit::kHandler,
             .tag = "system",
             .summary = "Online backup of the database into the server's backup folder",
             .success_status = 201,
             .handler = [&db, backup_dir](RequestContext& ctx) -> api::Result<Reply> {
               // 0700, like every folder the server makes (docs/SAFETY.md, "Files").
               if (auto made = storage::CreatePrivateFolders(backup_dir); !made.ok()) return made;
               std::error_code ec;
               std::string stamp = api::FormatUtc(db.Now());
               for (char& c : stamp) {
                 if (c == ':' || c == '.') c = '-';
               }
               const std::string path =
                   (std::filesystem::path(backup_dir) / ("fesbench-" + stamp + ".db")).string();
               if (auto st = db.Backup(path); !st.ok()) return st;
               const std::uintmax_t size = std::filesystem::file_size(path, ec);
               auto done = AuditedWrite<json>(
                   db, ctx, 201,
                   [&]() -> api::Result<json> {
                     return json{{"path", path}, {"size_bytes", ec ? 0 : size}};
                   },
                   [](const json&) { return std::string("backup"); });
               if (!done.ok()) return done.status();
               return JsonReply(std::move(*done), 201);
             }});
}

}  // namespace

void AddAdminRoutes(RouteTable& table, const ApiDependencies& deps) {
  AddUserRoutes(table, deps);
  AddTokenRoutes(table, deps);
  AddAuditAndBackupRoutes(table, deps);
}

}  // namespace fesbench::server::http
