// Integration: the bad-input battery (docs/API.md, "HTTP conventions"). Each hostile or broken
// request gets the right 4xx with a JSON error naming the problem, never a
// 5xx, and the server stays healthy afterwards.

#include <gtest/gtest.h>

#include "hostile_client_fixture.h"
#include "server_process.h"

namespace fesbench::testing {
namespace {

using nlohmann::json;

class BadInputTest : public HostileClientTest {
 protected:
  // Expects `status` with a JSON error whose code is `code` (and whose field
  // is `field` when given).
  void ExpectError(const JsonResponse& r, int status, const std::string& code,
                   const std::string& field = {}) {
    EXPECT_EQ(r.status, status) << r.text;
    ASSERT_TRUE(r.body.is_object()) << r.text;
    EXPECT_EQ(r.body["error"]["code"], code) << r.text;
    EXPECT_FALSE(r.body["error"]["message"].get<std::string>().empty());
    if (!field.empty()) {
      EXPECT_EQ(r.body["error"].value("field", ""), field) << r.text;
    }
  }
  std::string RawRequest(const std::string& head, const std::string& body = {}) {
    return RawExchange(server_->port(), head + "\r\n" + body);
  }

};

TEST_F(BadInputTest, MalformedJson) {
  auto r = client_->Post("/api/v1/subjects", {{"Authorization", "Bearer " + admin_}},
                         "{\"code\": \"A1\",", "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400);
  auto body = json::parse(r->body);
  EXPECT_EQ(body["error"]["code"], "invalid_argument");
  EXPECT_NE(body["error"]["message"].get<std::string>().find("malformed JSON"), std::string::npos);
  for (const char* text : {"", "[1,2]", "\"text\"", "nul", "{\"code\": \"\xff\xfe\"}"}) {
    auto bad = client_->Post("/api/v1/subjects", {{"Authorization", "Bearer " + admin_}}, text,
                             "application/json");
    ASSERT_TRUE(bad);
    EXPECT_EQ(bad->status, 400) << text;
  }
  std::string deep(10000, '[');
  auto nested = client_->Post("/api/v1/subjects", {{"Authorization", "Bearer " + admin_}}, deep,
                              "application/json");
  ASSERT_TRUE(nested);
  EXPECT_EQ(nested->status, 400);
}

TEST_F(BadInputTest, WrongTypesMissingFieldsOutOfRangeUnknownFields) {
  ExpectError(Call(*client_, "POST", "/api/v1/subjects", admin_, {{"code", 5}}), 400,
              "invalid_argument", "code");
  ExpectError(Call(*client_, "POST", "/api/v1/subjects", admin_, json::object()), 400,
              "invalid_argument", "code");
  ExpectError(Call(*client_, "POST", "/api/v1/subjects", admin_,
                   {{"code", "R1"}, {"details", {{"height_cm", 1000}}}}),
              400, "invalid_argument", "details.height_cm");
  ExpectError(Call(*client_, "POST", "/api/v1/subjects", admin_,
                   {{"code", "R1"}, {"details", {{"age_years", 30.5}}}}),
              400, "invalid_argument", "details.age_years");
  ExpectError(Call(*client_, "POST", "/api/v1/subjects", admin_, {{"code", "R1"}, {"colour", 1}}),
              400, "invalid_argument", "colour");
  ExpectError(Call(*client_, "POST", "/api/v1/subjects", admin_,
                   {{"code", "R1"}, {"legs", {"middle"}}}),
              400, "invalid_argument", "legs[0]");
  ASSERT_EQ(Call(*client_, "POST", "/api/v1/subjects", admin_, {{"code", "R1"}}).status, 201);
  ExpectError(Call(*client_, "POST", "/api/v1/subjects", admin_, {{"code", "R1"}}), 409,
              "already_exists", "code");
  ExpectError(Call(*client_, "POST", "/api/v1/subjects/1/sessions", admin_,
                   {{"leg", "right"}, {"date", "2026-13-45"}}),
              400, "invalid_argument", "date");
  ExpectError(Call(*client_, "POST", "/api/v1/subjects/1/sessions", admin_,
                   {{"leg", "right"}, {"date", "2026-11-21"}, {"threshold_ma", 150}}),
              400, "invalid_argument", "threshold_ma");
  ExpectError(Call(*client_, "POST", "/api/v1/subjects/1/sessions", admin_,
                   {{"leg", "right"}, {"date", "2026-11-21"}, {"threshold_ma", 30},
                    {"max_tolerated_ma", 20}}),
              400, "invalid_argument", "max_tolerated_ma");
  auto session = Call(*client_, "POST", "/api/v1/subjects/1/sessions", admin_,
                      {{"leg", "right"}, {"date", "2026-11-21"}, {"threshold_ma", 15},
                       {"max_tolerated_ma", 35}});
  ASSERT_EQ(session.status, 201);
  ExpectError(Call(*client_, "POST", "/api/v1/sessions/1/runs", admin_, {{"protocol", "nope"}}),
              404, "not_found", "protocol");
  ExpectError(Call(*client_, "POST", "/api/v1/sessions/1/runs", admin_,
                   {{"protocol", "isometric_ramp_irc"}, {"parameters", {{"max_ma", "high"}}}}),
              400, "invalid_argument", "parameters.max_ma");
  ExpectError(Call(*client_, "POST", "/api/v1/sessions/1/runs", admin_,
                   {{"protocol", "isometric_ramp_irc"}, {"parameters", {{"max_ma", 99}}}}),
              400, "invalid_argument", "parameters.max_ma");
  ExpectError(Call(*client_, "POST", "/api/v1/tokens", admin_, {{"user_id", -3}}), 400,
              "invalid_argument", "user_id");
  ExpectError(Call(*client_, "POST", "/api/v1/users", admin_, {{"name", "x"}, {"role", "root"}}),
              400, "invalid_argument", "role");
  ExpectError(Call(*client_, "PUT", "/api/v1/bench/virtual-subject", admin_, {{"truth", 1}}), 400,
              "invalid_argument");
  ExpectError(Call(*client_, "PUT", "/api/v1/bench/virtual-subject", admin_, {{"draw_seed", -4}}),
              400, "invalid_argument", "draw_seed");
  ExpectError(Call(*client_, "PUT", "/api/v1/bench/virtual-subject", admin_, {{"draw_seed", 1.5}}),
              400, "invalid_argument", "draw_seed");
  ExpectError(Call(*client_, "PUT", "/api/v1/bench/virtual-subject", admin_,
                   {{"draw_seed", 4}, {"seed", 4}}),
              400, "invalid_argument", "seed");
  ExpectError(Call(*client_, "POST", "/api/v1/identifications", admin_, {{"session_id", "one"}}),
              400, "invalid_argument", "session_id");
  ExpectError(Call(*client_, "POST", "/api/v1/predictions", admin_, {{"parameter_set_id", 1.5}}),
              400, "invalid_argument", "parameter_set_id");
  ExpectError(Call(*client_, "POST", "/api/v1/comparisons", admin_, {{"pairs", "all"}}), 400,
              "invalid_argument", "pairs");
}

TEST_F(BadInputTest, QueryParameters) {
  ExpectError(Call(*client_, "GET", "/api/v1/subjects?limit=0", admin_), 400, "invalid_argument",
              "limit");
  ExpectError(Call(*client_, "GET", "/api/v1/subjects?limit=501", admin_), 400,
              "invalid_argument", "limit");
  ExpectError(Call(*client_, "GET", "/api/v1/subjects?cursor=not-a-cursor", admin_), 400,
              "invalid_argument", "cursor");
  ExpectError(Call(*client_, "GET", "/api/v1/subjects?colour=red", admin_), 400,
              "invalid_argument", "colour");
  ExpectError(Call(*client_, "GET", "/api/v1/parameter-sets?subject_id=abc", admin_), 400,
              "invalid_argument", "subject_id");
  ExpectError(Call(*client_, "GET", "/api/v1/parameter-sets?from=yesterday", admin_), 400,
              "invalid_argument", "from");
  ExpectError(Call(*client_, "GET", "/api/v1/parameter-sets?subject_id=1&leg=middle", admin_),
              400, "invalid_argument", "leg");
  ExpectError(Call(*client_, "GET", "/api/v1/parameter-sets?subject_id=42", admin_), 404,
              "not_found");
}

TEST_F(BadInputTest, SqlLookingStringsAreDataNotCode) {
  ExpectError(Call(*client_, "POST", "/api/v1/subjects", admin_,
                   {{"code", "x'; DROP TABLE subjects;--"}}),
              400, "invalid_argument", "code");
  ExpectError(Call(*client_, "GET", "/api/v1/subjects?code=%27%20OR%201%3D1%20--", admin_), 400,
              "invalid_argument", "code");
  ASSERT_EQ(Call(*client_, "POST", "/api/v1/subjects", admin_, {{"code", "SQL-1"}}).status, 201);
  const std::string notes = "'); DELETE FROM subjects; SELECT * FROM users WHERE ('1'='1";
  auto session = Call(*client_, "POST", "/api/v1/subjects/1/sessions", admin_,
                      {{"leg", "left"}, {"date", "2026-11-21"}, {"notes", notes}});
  ASSERT_EQ(session.status, 201) << session.text;
  auto back = Call(*client_, "GET", "/api/v1/sessions/1", admin_);
  EXPECT_EQ(back.body["details"]["notes"], notes);
  auto subjects = Call(*client_, "GET", "/api/v1/subjects", admin_);
  EXPECT_EQ(subjects.body["items"].size(), 1u);
  auto user = Call(*client_, "POST", "/api/v1/users", admin_,
                   {{"name", "admin' --"}, {"role", "analyst"}});
  ASSERT_EQ(user.status, 201) << user.text;
  EXPECT_EQ(user.body["name"], "admin' --");
  EXPECT_EQ(user.body["role"], "analyst");
  ExpectError(Call(*client_, "POST", "/api/v1/users", admin_,
                   {{"name", "admin' --"}, {"role", "admin"}}),
              409, "already_exists", "name");
}

TEST_F(BadInputTest, PathTraversalUnknownRoutesAndMethods) {
  for (const char* path :
       {"/api/v1/../../etc/passwd", "/api/v1/subjects/../users", "/api/v1/subjects/%2e%2e/users",
        "/api/v1/subjects/..%2f..%2fetc%2fpasswd", "/../../../etc/passwd", "/etc/passwd",
        "/api/v1/subjects/1/../../users", "/api/v2/subjects", "/api/v1/subjects/abc",
        "/api/v1/subjects/0", "/api/v1/subjects/99999999999999999999999", "/api/v1//subjects",
        "/api/v1/subjects/"}) {  // "/" is the web client (static_files_test.cc, tests/browser)
    auto r = Call(*client_, "GET", path, admin_);
    ExpectError(r, 404, "not_found");
    EXPECT_EQ(r.text.find("root:"), std::string::npos);
  }
  ExpectError(Call(*client_, "GET", "/api/v1/subjects/424242", admin_), 404, "not_found");
  ExpectError(Call(*client_, "GET", "/api/v1/parameter-sets/424242", admin_), 404, "not_found");
  ExpectError(Call(*client_, "GET", "/api/v1/runs/424242", admin_), 404, "not_found");
  ExpectError(Call(*client_, "GET", "/api/v1/trials/424242", admin_), 404, "not_found");
  ExpectError(Call(*client_, "GET", "/api/v1/jobs/424242", admin_), 404, "not_found");
  auto patch = Call(*client_, "PATCH", "/api/v1/subjects", admin_, json::object());
  ExpectError(patch, 405, "method_not_allowed");
  EXPECT_NE(patch.text.find("GET"), std::string::npos);
  ExpectError(Call(*client_, "DELETE", "/api/v1/subjects/1", admin_), 405, "method_not_allowed");
  ExpectError(Call(*client_, "PUT", "/api/v1/health", ""), 405, "method_not_allowed");
  for (const char* method : {"TRACE", "CONNECT", "FOO", "get"}) {
    const std::string response =
        RawRequest(std::string(method) + " /api/v1/health HTTP/1.1\r\nHost: x\r\n");
    const int status = RawStatus(response);
    EXPECT_TRUE(status == 400 || status == 405) << method << ": " << response;
    EXPECT_NE(response.find("{\"error\""), std::string::npos) << response;
  }
}

TEST_F(BadInputTest, ContentTypeAndBodiesWhereNoneIsTaken) {
  auto text = client_->Post("/api/v1/subjects", {{"Authorization", "Bearer " + admin_}},
                            "{\"code\":\"CT1\"}", "text/plain");
  ASSERT_TRUE(text);
  EXPECT_EQ(text->status, 415);
  auto form = client_->Post("/api/v1/subjects", {{"Authorization", "Bearer " + admin_}},
                            "code=CT1", "application/x-www-form-urlencoded");
  ASSERT_TRUE(form);
  EXPECT_EQ(form->status, 415);
  auto charset = client_->Post("/api/v1/subjects", {{"Authorization", "Bearer " + admin_}},
                               "{\"code\":\"CT1\"}", "application/json; charset=utf-8");
  ASSERT_TRUE(charset);
  EXPECT_EQ(charset->status, 201);
  ExpectError(Call(*client_, "POST", "/api/v1/bench/estop", admin_, {{"why", "x"}}), 400,
              "invalid_argument");
}

// A ceiling_reason authorises stimulation above the recorded max
// (docs/SAFETY.md): only printable words do; nothing starts, nothing is audited.
TEST_F(BadInputTest, CeilingReasonMustBePrintableText) {
  auto subject =
      Call(*client_, "POST", "/api/v1/subjects", admin_, {{"code", "CEIL-1"}, {"legs", {"right"}}});
  ASSERT_EQ(subject.status, 201) << subject.text;
  auto session = Call(
      *client_, "POST",
      "/api/v1/subjects/" + std::to_string(subject.body["id"].get<int>()) + "/sessions", admin_,
      {{"leg", "right"}, {"date", "2026-11-25"}, {"threshold_ma", 3}, {"max_tolerated_ma", 8.5}});
  ASSERT_EQ(session.status, 201) << session.text;
  const std::string runs =
      "/api/v1/sessions/" + std::to_string(session.body["id"].get<int>()) + "/runs";
  for (const std::string& reason :
       {std::string(" "), std::string("\0x", 2), std::string(" \t "), std::string("ok\x7f"),
        std::string("new\nline"), std::string("\xc2\x85")}) {
    SCOPED_TRACE(json(reason).dump());
    auto r = Call(*client_, "POST", runs, admin_,
                  {{"protocol", "tolerance_test"},
                   {"parameters", {{"ceiling_ma", 20}}},
                   {"ceiling_reason", reason}});
    ExpectError(r, 400, "invalid_argument", "ceiling_reason");
    EXPECT_NE(r.body["error"]["message"].get<std::string>().find("printable"), std::string::npos)
        << r.text;
  }
  EXPECT_TRUE(Call(*client_, "GET", runs, admin_).body["items"].empty()) << "a run was created";
  const JsonResponse audit = Call(*client_, "GET", "/api/v1/audit", admin_);
  ASSERT_EQ(audit.status, 200);
  for (const json& e : audit.body["items"]) {
    EXPECT_NE(e["action"], "run.ceiling_above_max") << e.dump();
  }
}

TEST_F(BadInputTest, HugeBodyChunkedBodyAndThousandHeaders) {
  const std::string big(10 * 1024 * 1024, 'x');
  auto huge = client_->Post("/api/v1/subjects", {{"Authorization", "Bearer " + admin_}},
                            "{\"code\":\"" + big + "\"}", "application/json");
  ASSERT_TRUE(huge);
  EXPECT_EQ(huge->status, 413);
  EXPECT_NE(huge->body.find("payload_too_large"), std::string::npos);

  const std::string chunked = RawRequest(
      "POST /api/v1/subjects HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer " + admin_ +
          "\r\nContent-Type: application/json\r\nTransfer-Encoding: chunked\r\n",
      "e\r\n{\"code\":\"CH1\"}\r\n0\r\n\r\n");
  EXPECT_EQ(RawStatus(chunked), 411) << chunked;
  EXPECT_NE(chunked.find("length_required"), std::string::npos);
  // Nothing was created by the refused body.
  auto subjects = Call(*client_, "GET", "/api/v1/subjects?code=CH1", admin_);
  EXPECT_EQ(subjects.body["items"].size(), 0u);

  std::string headers = "GET /api/v1/health HTTP/1.1\r\nHost: x\r\n";
  for (int i = 0; i < 1000; ++i) headers += "X-Filler-" + std::to_string(i) + ": v\r\n";
  const std::string many = RawRequest(headers);
  EXPECT_EQ(RawStatus(many), 431) << many.substr(0, 200);

  const std::string long_header =
      RawRequest("GET /api/v1/health HTTP/1.1\r\nHost: x\r\nX-Long: " + std::string(100000, 'a') +
                 "\r\n");
  const int long_status = RawStatus(long_header);
  EXPECT_TRUE(long_status == 400 || long_status == 431 || long_status == -1) << long_status;

  const std::string get_with_body =
      RawRequest("GET /api/v1/health HTTP/1.1\r\nHost: x\r\nContent-Length: 5\r\n", "hello");
  EXPECT_EQ(RawStatus(get_with_body), 400);
}

}  // namespace
}  // namespace fesbench::testing
