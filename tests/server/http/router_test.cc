// Unit tests of the HTTP layer's pure parts: route matching, paging cursors,
// the status mapping, the OpenAPI builder and the server config reader.

#include "server/http/router.h"

#include <gtest/gtest.h>

#include "server/config.h"
#include "server/http/errors.h"
#include "server/http/openapi.h"
#include "server/http/routes_common.h"

namespace fesbench::server::http {
namespace {

using nlohmann::json;

Route MakeRoute(std::string method, std::string path,
                std::optional<Permission> permission = Permission::kRead) {
  Route r;
  r.method = std::move(method);
  r.path = std::move(path);
  r.permission = permission;
  r.tag = "t";
  r.summary = "s";
  r.handler = [](RequestContext&) -> api::Result<Reply> { return Reply{}; };
  return r;
}

TEST(RouterTest, MatchesTemplatesAndIds) {
  RouteTable table;
  table.Add(MakeRoute("GET", "/api/v1/subjects"));
  table.Add(MakeRoute("POST", "/api/v1/subjects"));
  table.Add(MakeRoute("GET", "/api/v1/subjects/{subject_id}"));
  table.Add(MakeRoute("GET", "/api/v1/protocols/{name}"));

  auto m = table.Match("GET", "/api/v1/subjects/42");
  ASSERT_NE(m.route, nullptr);
  EXPECT_EQ(m.route->path, "/api/v1/subjects/{subject_id}");
  EXPECT_EQ(m.path.at("subject_id"), "42");

  EXPECT_EQ(table.Match("GET", "/api/v1/subjects/abc").route, nullptr);
  EXPECT_EQ(table.Match("GET", "/api/v1/subjects/0").route, nullptr);
  EXPECT_EQ(table.Match("GET", "/api/v1/subjects/0042").route, nullptr);
  EXPECT_EQ(table.Match("GET", "/api/v1/subjects/1234567890123456789").route, nullptr);
  EXPECT_EQ(table.Match("GET", "/api/v1/subjects/../subjects").route, nullptr);
  EXPECT_EQ(table.Match("GET", "/api/v1/subjects/").route, nullptr);
  EXPECT_EQ(table.Match("GET", "/api/v1//subjects").route, nullptr);
  EXPECT_EQ(table.Match("GET", "api/v1/subjects").route, nullptr);
  EXPECT_EQ(table.Match("GET", "/api/v1/protocols/a.b").route, nullptr);
  EXPECT_NE(table.Match("GET", "/api/v1/protocols/rapid_parameterisation").route, nullptr);
  EXPECT_NE(table.Match("HEAD", "/api/v1/subjects").route, nullptr);

  auto wrong_method = table.Match("DELETE", "/api/v1/subjects");
  EXPECT_EQ(wrong_method.route, nullptr);
  EXPECT_EQ(wrong_method.allowed_methods, (std::vector<std::string>{"GET", "POST"}));
  EXPECT_TRUE(table.Match("GET", "/nothing").allowed_methods.empty());
}

TEST(PagingTest, CursorRoundTripsAndRejectsForgeries) {
  for (std::int64_t id : {0LL, 1LL, 57LL, 123456789012LL}) {
    EXPECT_EQ(DecodeCursor(EncodeCursor(id)), id);
  }
  EXPECT_FALSE(DecodeCursor("").has_value());
  EXPECT_FALSE(DecodeCursor("!!!").has_value());
  EXPECT_FALSE(DecodeCursor(EncodeCursor(5).substr(1)).has_value());
  std::vector<int> items = {1, 2, 3, 4, 5};
  auto page = MakePage(
      items, PageRequest{2, 2}, [](int i) { return i; }, [](int i) { return i; });
  EXPECT_EQ(page["items"], json({3, 4}));
  EXPECT_EQ(DecodeCursor(page["next_cursor"].get<std::string>()), 4);
  auto last = MakePage(
      items, PageRequest{2, 4}, [](int i) { return i; }, [](int i) { return i; });
  EXPECT_EQ(last["items"], json({5}));
  EXPECT_TRUE(last["next_cursor"].is_null());
}

TEST(ErrorsTest, OneMappingForEveryCode) {
  using api::ErrorCode;
  EXPECT_EQ(HttpStatusFor(ErrorCode::kInvalidArgument), 400);
  EXPECT_EQ(HttpStatusFor(ErrorCode::kUnauthenticated), 401);
  EXPECT_EQ(HttpStatusFor(ErrorCode::kPermissionDenied), 403);
  EXPECT_EQ(HttpStatusFor(ErrorCode::kNotFound), 404);
  EXPECT_EQ(HttpStatusFor(ErrorCode::kAlreadyExists), 409);
  EXPECT_EQ(HttpStatusFor(ErrorCode::kConflict), 409);
  EXPECT_EQ(HttpStatusFor(ErrorCode::kFailedPrecondition), 409);
  EXPECT_EQ(HttpStatusFor(ErrorCode::kUnavailable), 503);
  EXPECT_EQ(HttpStatusFor(ErrorCode::kPayloadTooLarge), 413);
  EXPECT_EQ(ErrorCodeName(ErrorCode::kPayloadTooLarge), "payload_too_large");
  EXPECT_EQ(HttpStatusFor(ErrorCode::kInternal), 500);
  auto j = ErrorJson(ToHttpError(api::Status::InvalidArgument("must be positive", "a.b")));
  EXPECT_EQ(
      j,
      json({{"error",
             {{"code", "invalid_argument"}, {"message", "must be positive"}, {"field", "a.b"}}}}));
  EXPECT_FALSE(ErrorJson(ToHttpError(api::Status::NotFound("x")))["error"].contains("field"));
}

TEST(OpenApiTest, DocumentsEveryRouteOfTheTable) {
  RouteTable table;
  table.Add(MakeRoute("GET", "/api/v1/health", std::nullopt));
  Route post = MakeRoute("POST", "/api/v1/subjects/{subject_id}/sessions", Permission::kRecord);
  post.json_body = true;
  post.query = {{"limit", "integer", "page size"}};
  table.Add(post);
  json doc = BuildOpenApi(table, "9.9");
  EXPECT_EQ(doc["openapi"], "3.0.3");
  ASSERT_EQ(doc["paths"].size(), 2u);
  EXPECT_EQ(doc["paths"]["/api/v1/health"]["get"]["security"], json::array());
  const json& op = doc["paths"]["/api/v1/subjects/{subject_id}/sessions"]["post"];
  EXPECT_EQ(op["x-roles"], json({"clinician", "admin"}));
  EXPECT_TRUE(op.contains("requestBody"));
  EXPECT_TRUE(op["responses"].contains("401"));
  EXPECT_TRUE(op["responses"].contains("403"));
  EXPECT_TRUE(op["responses"].contains("404"));
  EXPECT_TRUE(op["responses"].contains("415"));
  ASSERT_EQ(op["parameters"].size(), 2u);
  EXPECT_EQ(op["parameters"][0]["name"], "subject_id");
  EXPECT_EQ(op["parameters"][0]["in"], "path");
  EXPECT_EQ(op["parameters"][1]["in"], "query");
}

TEST(ServerConfigTest, FileKeysFlagsAndRanges) {
  ServerConfig c;
  ASSERT_TRUE(
      ApplyConfigJson(R"({"port": 0, "bench": "sim", "time-scale": 0, "db": "x.db"})", c).ok());
  EXPECT_EQ(c.port, 0);
  EXPECT_EQ(c.db, "x.db");
  EXPECT_EQ(c.time_scale, 0.0);
  EXPECT_TRUE(ValidateServerConfig(c).ok());
  EXPECT_EQ(ApplyConfigJson(R"({"prot": 1})", c).field(), "prot");
  EXPECT_EQ(ApplyConfigJson(R"({"port": 70000})", c).field(), "port");
  EXPECT_EQ(ApplyConfigJson(R"({"port": "80"})", c).field(), "port");
  c.bench = "replay";
  EXPECT_EQ(ValidateServerConfig(c).field(), "replay");
  c = ServerConfig{};
  c.tls_cert = "cert.pem";
  EXPECT_EQ(ValidateServerConfig(c).field(), "tls-cert");
  // The model gate's impact limit (default 500 deg/s), in (0, 2000].
  c = ServerConfig{};
  EXPECT_EQ(c.max_stop_impact_deg_s, 500.0);
  ASSERT_TRUE(ApplyConfigJson(R"({"max-stop-impact-deg-s": 300})", c).ok());
  EXPECT_EQ(c.max_stop_impact_deg_s, 300.0);
  c.max_stop_impact_deg_s = 0.0;
  EXPECT_EQ(ValidateServerConfig(c).field(), "max-stop-impact-deg-s");
  // Secured DDS: a PKI directory and an identity (default "server"); not with DDS off.
  c = ServerConfig{};
  EXPECT_EQ(c.dds_identity, "server");
  ASSERT_TRUE(ApplyConfigJson(R"({"dds-security": "pki", "dds-identity": "knee2"})", c).ok());
  EXPECT_EQ(c.dds_security, "pki");
  EXPECT_EQ(c.dds_identity, "knee2");
  EXPECT_TRUE(ValidateServerConfig(c).ok());
  c.dds_transport = "off";
  EXPECT_EQ(ValidateServerConfig(c).field(), "dds-security");
  // A ScienceMode2 stimulator needs its port; channels 1–8.
  c = ServerConfig{};
  EXPECT_EQ(c.stimulator, "sim");
  ASSERT_TRUE(ApplyConfigJson(R"({"stimulator": "sciencemode2", "stimulator-channel": 2})", c).ok());
  EXPECT_EQ(ValidateServerConfig(c).field(), "stimulator-port");
  ASSERT_TRUE(ApplyConfigJson(R"({"stimulator-port": "/dev/ttyUSB0"})", c).ok());
  EXPECT_TRUE(ValidateServerConfig(c).ok());
  EXPECT_EQ(c.stimulator_channel, 2);
  // A real stimulator runs in real time only.
  for (double scale : {0.0, 0.5, 10.0}) {
    c.time_scale = scale;
    const api::Status refused = ValidateServerConfig(c);
    EXPECT_EQ(refused.field(), "time-scale") << scale;
    EXPECT_NE(refused.message().find("--stimulator sciencemode2"), std::string::npos)
        << refused.message();
  }
  c.time_scale = 1.0;
  EXPECT_TRUE(ValidateServerConfig(c).ok());
  EXPECT_EQ(ApplyConfigJson(R"({"stimulator-channel": 9})", c).field(), "stimulator-channel");
  c.stimulator = "sciencemode4";  // a P24: channels 1–4
  EXPECT_TRUE(ValidateServerConfig(c).ok());
  c.stimulator_channel = 5;
  EXPECT_EQ(ValidateServerConfig(c).field(), "stimulator-channel");
  c.stimulator = "sciencemode5";
  EXPECT_EQ(ValidateServerConfig(c).field(), "stimulator");

  std::ostringstream out, err;
  const char* argv[] = {"fesbench-server", "--port", "0", "--time-scale", "0.5", "--bench", "sim"};
  auto parsed = ParseServerConfig(7, argv, out, err);
  ASSERT_FALSE(parsed.exit_code) << err.str();
  EXPECT_EQ(parsed.config.port, 0);
  EXPECT_EQ(parsed.config.time_scale, 0.5);
  EXPECT_EQ(parsed.config.bind, "127.0.0.1");
  const char* bad[] = {"fesbench-server", "--bench", "real"};
  EXPECT_EQ(ParseServerConfig(3, bad, out, err).exit_code, 2);
  const char* help[] = {"fesbench-server", "--help"};
  EXPECT_EQ(ParseServerConfig(2, help, out, err).exit_code, 0);
  EXPECT_NE(out.str().find("--time-scale"), std::string::npos);
}

// The maintenance steps the Debian package runs (server/database_maintenance.h):
// --backup with its retention (flag or "backup-keep-days", 1–3650 days), and
// --migrate; never both at once.
TEST(ServerConfigTest, BackupAndMigrateTasks) {
  std::ostringstream out, err;
  const char* serve[] = {"fesbench-server"};
  auto parsed = ParseServerConfig(1, serve, out, err);
  ASSERT_FALSE(parsed.exit_code) << err.str();
  EXPECT_EQ(parsed.config.task, ServerTask::kServe);
  EXPECT_EQ(parsed.config.backup_keep_days, 14);
  const char* backup[] = {"fesbench-server", "--backup", "--backup-keep-days", "30"};
  parsed = ParseServerConfig(4, backup, out, err);
  ASSERT_FALSE(parsed.exit_code) << err.str();
  EXPECT_EQ(parsed.config.task, ServerTask::kBackup);
  EXPECT_EQ(parsed.config.backup_keep_days, 30);
  const char* migrate[] = {"fesbench-server", "--migrate"};
  parsed = ParseServerConfig(2, migrate, out, err);
  ASSERT_FALSE(parsed.exit_code) << err.str();
  EXPECT_EQ(parsed.config.task, ServerTask::kMigrate);
  const char* both[] = {"fesbench-server", "--migrate", "--backup"};
  EXPECT_EQ(ParseServerConfig(3, both, out, err).exit_code, 2);
  const char* zero_days[] = {"fesbench-server", "--backup", "--backup-keep-days", "0"};
  EXPECT_EQ(ParseServerConfig(4, zero_days, out, err).exit_code, 2);
  ServerConfig c;
  ASSERT_TRUE(ApplyConfigJson(R"({"backup-keep-days": 7})", c).ok());
  EXPECT_EQ(c.backup_keep_days, 7);
  EXPECT_EQ(ApplyConfigJson(R"({"backup-keep-days": 0})", c).field(), "backup-keep-days");
}

}  // namespace
}  // namespace fesbench::server::http
