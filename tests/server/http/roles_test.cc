// Integration: access control over every route (docs/API.md, roles). Each route is
// tried with no token, a revoked token and each role: 401 without a valid
// token, 403 for a role not allowed, anything else (the handler ran) for an
// allowed role. The table below is this test's own inventory of the API;
// it must equal the routes the OpenAPI document lists and the roles column
// of docs/API.md's resource table, and every documented route must exist on
// the server.

#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <thread>

#include "server_process.h"

namespace fesbench::testing {
namespace {

using nlohmann::json;

struct Expectation {
  const char* method;
  const char* path;  // OpenAPI template
  const char* roles;  // "open", or letters c (clinician), a (analyst), d (admin)
};

// docs/API.md, roles: clinicians write subjects, sessions, their trials and
// runs; analysts read and analyse; admin may do everything.
const Expectation kRoutes[] = {
    {"GET", "/api/v1/health", "open"},
    {"GET", "/api/v1/openapi.json", "open"},
    {"GET", "/api/v1/subjects", "cad"},
    {"POST", "/api/v1/subjects", "cd"},
    {"GET", "/api/v1/subjects/{subject_id}", "cad"},
    {"PATCH", "/api/v1/subjects/{subject_id}", "cd"},
    {"GET", "/api/v1/subjects/{subject_id}/revisions", "cad"},
    {"GET", "/api/v1/subjects/{subject_id}/sessions", "cad"},
    {"POST", "/api/v1/subjects/{subject_id}/sessions", "cd"},
    {"GET", "/api/v1/sessions/{session_id}", "cad"},
    {"PATCH", "/api/v1/sessions/{session_id}", "cd"},
    {"GET", "/api/v1/sessions/{session_id}/revisions", "cad"},
    {"GET", "/api/v1/sessions/{session_id}/runs", "cad"},
    {"POST", "/api/v1/sessions/{session_id}/runs", "cd"},
    {"GET", "/api/v1/sessions/{session_id}/trials", "cad"},
    {"POST", "/api/v1/sessions/{session_id}/trials", "cd"},
    {"GET", "/api/v1/sessions/{session_id}/export", "cad"},
    {"GET", "/api/v1/sessions/{session_id}/report", "cad"},
    {"GET", "/api/v1/trial-kinds", "cad"},
    {"GET", "/api/v1/runs/{run_id}", "cad"},
    {"POST", "/api/v1/runs/{run_id}/cancel", "cd"},
    {"POST", "/api/v1/runs/{run_id}/stop", "cd"},
    {"POST", "/api/v1/runs/{run_id}/heartbeat", "cd"},
    {"GET", "/api/v1/runs/{run_id}/stream", "cad"},
    {"GET", "/api/v1/events/parameter-sets", "cad"},
    {"GET", "/api/v1/trials/{trial_id}", "cad"},
    {"GET", "/api/v1/parameter-sets", "cad"},
    {"GET", "/api/v1/parameter-sets/{parameter_set_id}", "cad"},
    {"GET", "/api/v1/parameter-sets/{parameter_set_id}/predictions", "cad"},
    {"POST", "/api/v1/parameter-sets/{parameter_set_id}/approve", "cd"},
    {"GET", "/api/v1/subjects/{subject_id}/legs/{leg}/approved-parameter-set", "cad"},
    {"GET", "/api/v1/predictions/{prediction_id}", "cad"},
    {"POST", "/api/v1/identifications", "ad"},
    {"POST", "/api/v1/predictions", "cad"},
    {"POST", "/api/v1/parameter-sets/{parameter_set_id}/model-check", "cad"},
    {"POST", "/api/v1/comparisons", "ad"},
    {"GET", "/api/v1/jobs", "ad"},
    {"GET", "/api/v1/jobs/{job_id}", "cad"},
    {"GET", "/api/v1/protocols", "cad"},
    {"GET", "/api/v1/protocols/{name}", "cad"},
    {"GET", "/api/v1/bench", "cad"},
    {"POST", "/api/v1/bench/estop", "cad"},
    {"DELETE", "/api/v1/bench/estop", "cd"},
    {"GET", "/api/v1/bench/virtual-subject", "d"},
    {"PUT", "/api/v1/bench/virtual-subject", "d"},
    {"GET", "/api/v1/me", "cad"},
    {"GET", "/api/v1/users", "d"},
    {"POST", "/api/v1/users", "d"},
    {"POST", "/api/v1/users/{user_id}/deactivate", "d"},
    {"GET", "/api/v1/tokens", "d"},
    {"POST", "/api/v1/tokens", "d"},
    {"DELETE", "/api/v1/tokens/{token_id}", "d"},
    {"GET", "/api/v1/audit", "d"},
    {"POST", "/api/v1/backup", "d"},
};

// A concrete path: ids that do not exist, names that do not exist.
std::string Concrete(std::string path) {
  for (std::size_t open = path.find('{'); open != std::string::npos; open = path.find('{')) {
    const std::size_t close = path.find('}', open);
    const std::string name = path.substr(open + 1, close - open - 1);
    path.replace(open, close - open + 1, name.ends_with("id") ? "987654" : "no_such_name");
  }
  // The endless event stream: end it after a second.
  if (path.starts_with("/api/v1/events/")) path += "?timeout_s=1";
  return path;
}

// The body a route gets in these probes: an empty object for body routes.
json ProbeBody(const std::string& method, const json& doc, const std::string& path) {
  std::string lower = method;
  for (char& c : lower) c = static_cast<char>(std::tolower(c));
  if (doc["paths"][path][lower].contains("requestBody")) return json::object();
  return nullptr;
}

bool IsNoRoute(const JsonResponse& r) {
  return (r.status == 404 && r.body.is_object() &&
          r.body["error"]["message"].get<std::string>().rfind("no route", 0) == 0) ||
         r.status == 405;
}

TEST(RolesTest, EveryRouteWithNoTokenEachRoleAndARevokedToken) {
  // Two failed tokens per route: more than a burst the server lets through.
  ServerProcess server({"--auth-failure-burst", "100000"});
  auto client = server.Client();
  const std::string admin = server.admin_token();
  const std::string clinician = CreateUserToken(client, admin, "cli", "clinician");
  const std::string analyst = CreateUserToken(client, admin, "ana", "analyst");
  const std::string revoked = CreateUserToken(client, admin, "gone", "analyst");
  auto tokens = Call(client, "GET", "/api/v1/tokens", admin);
  ASSERT_EQ(tokens.status, 200);
  const std::int64_t revoked_id = tokens.body["items"].back()["id"];
  ASSERT_EQ(Call(client, "DELETE", "/api/v1/tokens/" + std::to_string(revoked_id), admin).status,
            200);
  tokens = Call(client, "GET", "/api/v1/tokens", admin);
  EXPECT_TRUE(tokens.body["items"].back()["revoked"].get<bool>());
  EXPECT_FALSE(tokens.body["items"].back().contains("token")) << "secrets are never listed";

  auto doc = Call(client, "GET", "/api/v1/openapi.json", "");
  ASSERT_EQ(doc.status, 200);

  const std::pair<char, std::string> roles[] = {{'c', clinician}, {'a', analyst}, {'d', admin}};
  for (const auto& route : kRoutes) {
    SCOPED_TRACE(std::string(route.method) + " " + route.path);
    const std::string path = Concrete(route.path);
    const json body = ProbeBody(route.method, doc.body, route.path);
    const std::string allowed = route.roles;
    if (allowed == "open") {
      EXPECT_EQ(Call(client, route.method, path, "", body).status, 200);
      continue;
    }
    auto anonymous = Call(client, route.method, path, "", body);
    EXPECT_EQ(anonymous.status, 401) << anonymous.text;
    EXPECT_EQ(anonymous.body["error"]["code"], "unauthenticated");
    EXPECT_EQ(Call(client, route.method, path, revoked, body).status, 401);
    EXPECT_EQ(Call(client, route.method, path, "fsb_" + std::string(64, '0'), body).status, 401);
    for (const auto& [letter, token] : roles) {
      auto r = Call(client, route.method, path, token, body);
      if (allowed.find(letter) != std::string::npos) {
        EXPECT_NE(r.status, 401) << letter << ": " << r.text;
        EXPECT_NE(r.status, 403) << letter << ": " << r.text;
        EXPECT_FALSE(IsNoRoute(r)) << letter << ": " << r.text;
        EXPECT_LT(r.status, 500) << letter << ": " << r.text;
      } else {
        EXPECT_EQ(r.status, 403) << letter << ": " << r.text;
        EXPECT_EQ(r.body["error"]["code"], "permission_denied");
      }
    }
  }
  EXPECT_EQ(Call(client, "GET", "/api/v1/health", "").status, 200);
  EXPECT_EQ(server.Terminate(), 0);
  EXPECT_EQ(server.Stderr().find("internal error"), std::string::npos) << server.Stderr();
}

TEST(RolesTest, OpenApiDocumentsExactlyTheServedRoutes) {
  ServerProcess server;
  auto client = server.Client();
  auto doc = Call(client, "GET", "/api/v1/openapi.json", "");
  ASSERT_EQ(doc.status, 200);
  EXPECT_EQ(doc.body["openapi"].get<std::string>().substr(0, 2), "3.");

  std::set<std::string> documented, inventory;
  for (const auto& [path, operations] : doc.body["paths"].items()) {
    for (const auto& [method, operation] : operations.items()) {
      std::string upper = method;
      for (char& c : upper) c = static_cast<char>(std::toupper(c));
      documented.insert(upper + " " + path);
      EXPECT_TRUE(operation.contains("responses")) << path;
      EXPECT_TRUE(operation.contains("summary")) << path;
      // Every documented route exists: the server does not answer "no route".
      auto r = Call(client, upper, Concrete(path), server.admin_token(),
                    ProbeBody(upper, doc.body, path));
      EXPECT_FALSE(IsNoRoute(r)) << upper << " " << path << ": " << r.text;
      EXPECT_LT(r.status, 500) << upper << " " << path << ": " << r.text;
    }
  }
  for (const auto& route : kRoutes) inventory.insert(std::string(route.method) + " " + route.path);
  // Every route of the API is documented, and nothing else is.
  for (const auto& r : inventory) EXPECT_TRUE(documented.contains(r)) << "undocumented: " << r;
  for (const auto& r : documented) EXPECT_TRUE(inventory.contains(r)) << "unexpected: " << r;
  // A path outside the document is not served.
  auto unknown = Call(client, "GET", "/api/v1/not-a-resource", server.admin_token());
  EXPECT_TRUE(IsNoRoute(unknown));
  EXPECT_EQ(server.Terminate(), 0);
}

// "METHOD /api/v1/a/{}/b": the route with its path parameters unnamed, as
// docs/API.md names them differently ({id}) from the route table.
std::string RouteKey(const std::string& method, std::string path) {
  if (!path.starts_with("/api/v1")) path = "/api/v1" + path;
  path = path.substr(0, path.find('?'));
  return method + " " + std::regex_replace(path, std::regex(R"(\{[^}]*\})"), "{}");
}

// The roles column of docs/API.md ("open", "any", "clinician, admin", …)
// as this file's letters.
std::string RoleLetters(const std::string& column) {
  if (column == "open") return "open";
  if (column == "any") return "cad";
  std::string letters;
  if (column.find("clinician") != std::string::npos) letters += 'c';
  if (column.find("analyst") != std::string::npos) letters += 'a';
  if (column.find("admin") != std::string::npos) letters += 'd';
  return letters;
}

// docs/API.md's resource table: route key → role letters.
std::map<std::string, std::string> DocumentedRoles() {
  std::ifstream in(std::string(FESBENCH_SOURCE_DIR) + "/docs/API.md");
  EXPECT_TRUE(in.good()) << "docs/API.md not found";
  std::map<std::string, std::string> roles;
  const std::regex row(R"(^\| (`[A-Z]+ [^|]*`) \| ([^|]+) \|)");
  const std::regex route("`([A-Z]+) (/[^`]*)`");
  std::string line;
  while (std::getline(in, line)) {
    std::smatch m;
    if (!std::regex_search(line, m, row)) continue;
    const std::string letters =
        RoleLetters(m[2].str().substr(0, m[2].str().find_last_not_of(' ') + 1));
    const std::string routes = m[1];
    for (std::sregex_iterator it(routes.begin(), routes.end(), route), end; it != end; ++it) {
      roles[RouteKey((*it)[1], (*it)[2])] = letters;
    }
  }
  return roles;
}

// The role table the docs give is the one the server enforces: every route,
// with the same roles, and nothing else.
TEST(RolesTest, DocsRoleTableIsTheRouteTable) {
  const std::map<std::string, std::string> documented = DocumentedRoles();
  std::set<std::string> served;
  for (const auto& route : kRoutes) {
    const std::string key = RouteKey(route.method, route.path);
    served.insert(key);
    const auto it = documented.find(key);
    if (it == documented.end()) {
      ADD_FAILURE() << "docs/API.md does not list " << key;
      continue;
    }
    EXPECT_EQ(it->second, route.roles) << key << ": docs/API.md and the route table disagree";
  }
  for (const auto& [key, letters] : documented) {
    EXPECT_TRUE(served.contains(key)) << "docs/API.md lists " << key << ", which is not served";
  }
}

// Writing trials into a session is a clinician's: an analyst's import, of
// a body a clinician may import, is refused, audited, and stores nothing.
TEST(RolesTest, AnAnalystsImportIsRefusedAndStoresNothing) {
  ServerProcess server;
  auto client = server.Client();
  const std::string admin = server.admin_token();
  const std::string clinician = CreateUserToken(client, admin, "cli", "clinician");
  const std::string analyst = CreateUserToken(client, admin, "ana", "analyst");
  auto subject =
      Call(client, "POST", "/api/v1/subjects", clinician, {{"code", "IMP-R"}, {"legs", {"right"}}});
  ASSERT_EQ(subject.status, 201) << subject.text;
  auto session =
      Call(client, "POST",
           "/api/v1/subjects/" + std::to_string(subject.body["id"].get<int>()) + "/sessions",
           clinician, {{"leg", "right"}, {"date", "2026-11-25"}});
  ASSERT_EQ(session.status, 201) << session.text;
  const std::string trials =
      "/api/v1/sessions/" + std::to_string(session.body["id"].get<int>()) + "/trials";
  const json recording = {{"spec",
                           {{"kind", "free_swing_passive"},
                            {"format", "csv"},
                            {"time_column", "t_s"},
                            {"columns", {{{"column", "angle_deg"}, {"channel", "angle_deg"}}}}}},
                          {"data", "t_s,angle_deg\n0,90\n0.005,89.5\n0.01,89\n"}};

  auto refused = Call(client, "POST", trials, analyst, recording);
  EXPECT_EQ(refused.status, 403) << refused.text;
  EXPECT_EQ(refused.body["error"]["code"], "permission_denied");
  auto archive = client.Post(trials + "?name=s.zip", {{"Authorization", "Bearer " + analyst}},
                             std::string("PK\x03\x04", 4), "application/zip");
  ASSERT_TRUE(archive);
  EXPECT_EQ(archive->status, 403) << archive->body;
  auto none = Call(client, "GET", trials, analyst);
  ASSERT_EQ(none.status, 200);
  EXPECT_TRUE(none.body["items"].empty()) << "a refused import stored something";
  auto sets = Call(client, "GET", "/api/v1/parameter-sets", analyst);
  ASSERT_EQ(sets.status, 200);
  EXPECT_TRUE(sets.body["items"].empty());
  int denied = 0;
  const JsonResponse audit = Call(client, "GET", "/api/v1/audit", admin);
  ASSERT_EQ(audit.status, 200);
  for (const json& e : audit.body["items"]) {
    if (e["outcome"] == "403 permission_denied" && e["action"] == "POST " + trials) {
      EXPECT_EQ(e["actor"], "ana");
      ++denied;
    }
  }
  EXPECT_EQ(denied, 2);

  auto imported = Call(client, "POST", trials, clinician, recording);
  EXPECT_EQ(imported.status, 201) << "the same body from a clinician: " << imported.text;
  EXPECT_EQ(Call(client, "GET", trials, analyst).body["items"].size(), 1u);
  EXPECT_EQ(server.Terminate(), 0);
}

// Sign-in failures (docs/SAFETY.md) over HTTP: failed sign-ins and role refusals (also of a GET)
// are audited; a burst of failed tokens from one address gets 429 with
// Retry-After (audited once) and no token lookup.
TEST(RolesTest, FailedTokensAreAuditedAndABurstIsSlowedDown) {
  ServerProcess server({"--auth-failure-burst", "5"});
  auto client = server.Client();
  const std::string admin = server.admin_token();
  const std::string analyst = CreateUserToken(client, admin, "ana", "analyst");
  EXPECT_EQ(Call(client, "GET", "/api/v1/users", analyst).status, 403);
  const std::string wrong = "fsb_" + std::string(64, '7');
  for (int k = 0; k < 5; ++k) {
    EXPECT_EQ(Call(client, "GET", "/api/v1/subjects", wrong).status, 401) << k;
  }
  auto slowed = Call(client, "GET", "/api/v1/subjects", wrong);
  EXPECT_EQ(slowed.status, 429) << slowed.text;
  EXPECT_EQ(slowed.body["error"]["code"], "too_many_requests");
  const auto retry = slowed.headers.find("Retry-After");
  ASSERT_NE(retry, slowed.headers.end());
  EXPECT_EQ(retry->second, "1") << "one failure regained per second";
  EXPECT_EQ(Call(client, "GET", "/api/v1/subjects", wrong).status, 429);

  // After Retry-After the address may present a token again (the admin's
  // token may have left the 2 s cache by now: it is checked, not refused).
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));

  auto audit = Call(client, "GET", "/api/v1/audit?limit=500", admin);
  ASSERT_EQ(audit.status, 200) << audit.text;
  int failed = 0, slowed_rows = 0, denied = 0;
  for (const json& e : audit.body["items"]) {
    const std::string outcome = e["outcome"];
    if (outcome == "401 unauthenticated") {
      ++failed;
      EXPECT_EQ(e["actor"], "127.0.0.1");
      EXPECT_EQ(e["action"], "GET /api/v1/subjects");
      EXPECT_EQ(e.dump().find(wrong), std::string::npos) << "never the token";
    }
    if (outcome == "429 too_many_requests") ++slowed_rows;
    if (outcome == "403 permission_denied" && e["action"] == "GET /api/v1/users") {
      ++denied;
      EXPECT_EQ(e["actor"], "ana");
    }
  }
  EXPECT_EQ(failed, 5);
  EXPECT_EQ(slowed_rows, 1);
  EXPECT_EQ(denied, 1);
  EXPECT_EQ(server.Terminate(), 0);
}

}  // namespace
}  // namespace fesbench::testing
