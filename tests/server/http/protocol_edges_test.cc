// Integration: the HTTP front end's protocol edges against the real server
// on loopback (docs/ARCHITECTURE.md, "Inside the server"): numbers beyond double range, a
// second server on a port in use, half-closed requests, pipelining, invalid
// Content-Length, Range on API answers, one Connection header, absolute-form
// request lines.

#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <thread>

#include "hostile_client_fixture.h"
#include "server_process.h"

namespace fesbench::testing {
namespace {

using nlohmann::json;
using std::chrono::milliseconds;

class ProtocolEdgesTest : public HostileClientTest {
 protected:
  static bool HasWholeResponse(const std::string& bytes) { return CountResponses(bytes) >= 1; }
};

int StatusOf(const std::string& response) { return RawStatus(response); }

std::size_t Occurrences(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// Item 5: a number beyond double range is a 400 naming the field, audited.
TEST_F(ProtocolEdgesTest, NumberOverflowIsA400NamingTheFieldAndAudited) {
  for (const char* body : {R"({"code":"n2","details":{"weight_kg":1e400}})",
                           R"({"code":"n2","details":{"weight_kg":-1e400}})"}) {
    auto r = client_->Post("/api/v1/subjects", {{"Authorization", "Bearer " + admin_}}, body,
                           "application/json");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 400) << r->body;
    auto error = json::parse(r->body)["error"];
    EXPECT_EQ(error["code"], "invalid_argument");
    EXPECT_EQ(error.value("field", ""), "details.weight_kg") << r->body;
  }
  auto top = client_->Post("/api/v1/subjects", {{"Authorization", "Bearer " + admin_}},
                           R"({"code":1e999})", "application/json");
  ASSERT_TRUE(top);
  EXPECT_EQ(top->status, 400);
  EXPECT_EQ(json::parse(top->body)["error"].value("field", ""), "code");
  auto array = client_->Post("/api/v1/subjects", {{"Authorization", "Bearer " + admin_}},
                             R"({"code":"x","legs":["left",2,1e400]})", "application/json");
  ASSERT_TRUE(array);
  EXPECT_EQ(array->status, 400);
  EXPECT_EQ(json::parse(array->body)["error"].value("field", ""), "legs[2]");

  auto audit = Call(*client_, "GET", "/api/v1/audit?limit=50", admin_);
  ASSERT_EQ(audit.status, 200);
  int refusals = 0;
  for (const auto& entry : audit.body["items"]) {
    if (entry.dump().find("400") != std::string::npos &&
        entry.dump().find("/api/v1/subjects") != std::string::npos) {
      ++refusals;
    }
  }
  EXPECT_GE(refusals, 4) << audit.body.dump();
}

// Item 7: a second server on the port of a running one fails "address in use".
TEST_F(ProtocolEdgesTest, SecondServerOnTheSamePortFails) {
  const auto dir = server_->dir() / "second";
  std::filesystem::create_directories(dir);
  int pipe_fds[2];
  ASSERT_EQ(::pipe(pipe_fds), 0);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ::dup2(pipe_fds[1], STDOUT_FILENO);
    ::dup2(pipe_fds[1], STDERR_FILENO);
    ::close(pipe_fds[0]);
    const std::string port = std::to_string(server_->port());
    const std::string db = (dir / "fesbench.db").string();
    ::execl(FESBENCH_SERVER_BINARY, FESBENCH_SERVER_BINARY, "--port", port.c_str(), "--db",
            db.c_str(), "--time-scale", "0", "--dds-transport", "off", nullptr);
    ::_exit(127);
  }
  ::close(pipe_fds[1]);
  std::string output;
  char buffer[4096];
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  int status = 0;
  bool exited = false;
  while (std::chrono::steady_clock::now() < deadline) {
    pollfd p{pipe_fds[0], POLLIN, 0};
    if (::poll(&p, 1, 50) > 0) {
      const ssize_t n = ::read(pipe_fds[0], buffer, sizeof buffer);
      if (n > 0) output.append(buffer, static_cast<std::size_t>(n));
    }
    if (::waitpid(pid, &status, WNOHANG) == pid) {
      exited = true;
      break;
    }
  }
  ::close(pipe_fds[0]);
  if (!exited) {
    ::kill(pid, SIGKILL);
    ::waitpid(pid, &status, 0);
  }
  ASSERT_TRUE(exited) << "the second server kept running: " << output;
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) != 0) << output;
  EXPECT_NE(output.find("address in use"), std::string::npos) << output;
  EXPECT_EQ(output.find("listening on"), std::string::npos) << output;
}

// Item 8: a POST whose client half-closes after the body is answered.
TEST_F(ProtocolEdgesTest, HalfClosedPostIsAnswered) {
  for (int i = 0; i < 5; ++i) {
    RawConnection c(server_->port());
    ASSERT_TRUE(c.ok());
    const std::string body = "{\"code\":\"HC" + std::to_string(i) + "\"}";
    ASSERT_TRUE(c.Send("POST /api/v1/subjects HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer " +
                       admin_ + "\r\nContent-Type: application/json\r\nContent-Length: " +
                       std::to_string(body.size()) + "\r\n\r\n" + body));
    c.HalfClose();
    const std::string response = c.ReadUntil(HasWholeResponse, milliseconds(3000));
    EXPECT_EQ(StatusOf(response), 201) << i << ": " << response;
  }
}

// Compression: gzip when asked for, never brotli (the packaged library's
// brotli compresses about 0.6 MB/s; gzip milliseconds), whatever the order.
TEST_F(ProtocolEdgesTest, AnswersAreGzippedNeverBrotli) {
  const auto encoding_of = [&](const std::string& accept) {
    const std::string response =
        RawExchange(server_->port(), "GET /api/v1/openapi.json HTTP/1.1\r\nHost: x\r\n" +
                                         (accept.empty() ? "" : "Accept-Encoding: " + accept +
                                                                    "\r\n") +
                                         "Connection: close\r\n\r\n");
    EXPECT_EQ(StatusOf(response), 200) << response.substr(0, 200);
    const std::size_t head_end = response.find("\r\n\r\n");
    std::string head = response.substr(0, head_end);
    for (char& ch : head) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    const std::size_t at = head.find("content-encoding: ");
    if (at == std::string::npos) return std::string("identity");
    return head.substr(at + 18, head.find("\r\n", at) - at - 18);
  };
  EXPECT_EQ(encoding_of("gzip, deflate, br"), "gzip");
  EXPECT_EQ(encoding_of("br;q=1.0, gzip;q=0.5"), "gzip");
  EXPECT_EQ(encoding_of("BR"), "identity");
  EXPECT_EQ(encoding_of("br"), "identity");
  EXPECT_EQ(encoding_of(""), "identity");
}

// Item 8: 50 pipelined requests on one connection get 50 answers, in order.
TEST_F(ProtocolEdgesTest, PipelinedRequestsAreAllAnswered) {
  RawConnection c(server_->port());
  ASSERT_TRUE(c.ok());
  std::string requests;
  for (int i = 0; i < 50; ++i) requests += "GET /api/v1/health HTTP/1.1\r\nHost: x\r\n\r\n";
  requests += "GET /api/v1/nothing-here HTTP/1.1\r\nHost: x\r\n\r\n";
  ASSERT_TRUE(c.Send(requests));
  const std::string responses = c.ReadUntil(
      [](const std::string& r) { return CountResponses(r) >= 51; }, milliseconds(5000));
  EXPECT_EQ(CountResponses(responses), 51);
  EXPECT_EQ(Occurrences(responses, "HTTP/1.1 200 OK"), 50u);
  // The last answer is the 404 of the last request: order kept.
  EXPECT_NE(responses.rfind("HTTP/1.1 404"), std::string::npos);
  EXPECT_GT(responses.rfind("HTTP/1.1 404"), responses.rfind("HTTP/1.1 200"));
  // And with the whole batch sent half-closed, every answer still comes.
  RawConnection d(server_->port());
  ASSERT_TRUE(d.Send(requests));
  d.HalfClose();
  EXPECT_EQ(CountResponses(d.ReadUntil([](const std::string& r) { return CountResponses(r) >= 51; },
                                       milliseconds(5000))),
            51);
}

// Item 8: an invalid Content-Length is refused at once (well before the
// 5 s request deadline), with a JSON error.
TEST_F(ProtocolEdgesTest, InvalidContentLengthIsRefusedAtOnce) {
  const std::pair<const char*, int> cases[] = {
      {"-1", 400}, {"18446744073709551617", 413}, {"abc", 400}, {"5, 5", 400}, {"", 400},
      {"99999999999", 413}};
  for (const auto& [value, expected] : cases) {
    RawConnection c(server_->port());
    const auto start = std::chrono::steady_clock::now();
    ASSERT_TRUE(c.Send(std::string("POST /api/v1/subjects HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer ") +
                       admin_ + "\r\nContent-Type: application/json\r\nContent-Length: " + value +
                       "\r\n\r\n{}"));
    const std::string response = c.ReadUntil(HasWholeResponse, milliseconds(4000));
    const auto took = std::chrono::steady_clock::now() - start;
    EXPECT_EQ(StatusOf(response), expected) << value << ": " << response;
    EXPECT_NE(response.find("{\"error\""), std::string::npos) << response;
    EXPECT_LT(took, std::chrono::milliseconds(2500)) << value;
  }
  // Two different lengths: refused.
  const std::string twice = RawExchange(
      server_->port(),
      "POST /api/v1/subjects HTTP/1.1\r\nHost: x\r\nContent-Length: 2\r\nContent-Length: 3\r\n\r\n{}");
  EXPECT_EQ(StatusOf(twice), 400) << twice;
}

// Item 8: a Range header never turns an API answer into multipart/byteranges.
TEST_F(ProtocolEdgesTest, RangeDoesNotCutApiAnswers) {
  for (const char* range : {"bytes=0-1,2-3", "bytes=0-1"}) {
    auto missing = client_->Get("/api/v1/nothing-here", {{"Range", range}});
    ASSERT_TRUE(missing);
    EXPECT_EQ(missing->status, 404);
    EXPECT_EQ(missing->get_header_value("Content-Type"), "application/json");
    EXPECT_EQ(json::parse(missing->body)["error"]["code"], "not_found");
    auto health = client_->Get("/api/v1/health", {{"Range", range}});
    ASSERT_TRUE(health);
    EXPECT_EQ(health->status, 200);
    EXPECT_EQ(json::parse(health->body)["status"], "ok") << health->body;
  }
}

// Item 8: refused requests carry exactly one "Connection: close".
TEST_F(ProtocolEdgesTest, OneConnectionCloseHeader) {
  const std::string chunked = RawExchange(
      server_->port(),
      "POST /api/v1/subjects HTTP/1.1\r\nHost: x\r\nConnection: keep-alive\r\nContent-Type: "
      "application/json\r\nTransfer-Encoding: chunked\r\n\r\n2\r\n{}\r\n0\r\n\r\n");
  EXPECT_EQ(StatusOf(chunked), 411) << chunked;
  EXPECT_EQ(Occurrences(chunked, "Connection:"), 1u) << chunked;
  const std::string get_body = RawExchange(
      server_->port(), "GET /api/v1/health HTTP/1.1\r\nHost: x\r\nContent-Length: 5\r\n\r\nhello");
  EXPECT_EQ(StatusOf(get_body), 400) << get_body;
  EXPECT_EQ(Occurrences(get_body, "Connection:"), 1u) << get_body;
  const std::string closing = RawExchange(
      server_->port(), "GET /api/v1/health HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
  EXPECT_EQ(StatusOf(closing), 200) << closing;
  EXPECT_EQ(Occurrences(closing, "Connection:"), 1u) << closing;
}

// Item 8: an absolute-form request line is served like its origin form.
TEST_F(ProtocolEdgesTest, AbsoluteFormRequestLine) {
  const std::string response = RawExchange(
      server_->port(), "GET http://127.0.0.1/api/v1/health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
  EXPECT_EQ(StatusOf(response), 200) << response;
  const std::string me = RawExchange(
      server_->port(), "GET HTTP://localhost:1/api/v1/me?x=1 HTTP/1.1\r\nHost: x\r\n"
                       "Authorization: Bearer " + admin_ + "\r\n\r\n");
  EXPECT_EQ(StatusOf(me), 400) << me;  // the unknown query parameter, so the route matched
  EXPECT_NE(me.find("\"field\":\"x\""), std::string::npos) << me;
}

// A request that never completes is answered 408 at its deadline; bare LF
// and NUL bytes are refused.
TEST_F(ProtocolEdgesTest, IncompleteAndMalformedHeads) {
  RawConnection c(server_->port());
  ASSERT_TRUE(c.Send("GET /api/v1/health HTTP/1.1\r\nHost: x\r\n"));
  const std::string timeout = c.ReadUntil(HasWholeResponse, milliseconds(9000));
  EXPECT_EQ(StatusOf(timeout), 408) << timeout;
  EXPECT_EQ(StatusOf(RawExchange(server_->port(), "GET /api/v1/health HTTP/1.1\nHost: x\n\n")), 400);
  const char nul[] = "GET /api/v1/health HTTP/1.1\r\nX: a\0b\r\n\r\n";
  EXPECT_EQ(StatusOf(RawExchange(server_->port(), std::string(nul, sizeof nul - 1))), 400);
  EXPECT_EQ(StatusOf(RawExchange(server_->port(), "GET /api/v1/health HTTP/2.0\r\n\r\n")), 400);
  EXPECT_EQ(StatusOf(RawExchange(server_->port(), "GET /api/v1/health HTTP/1.1\r\nX: a\r\n b\r\n\r\n")), 400);
  // Empty lines before a request are skipped (RFC 9112 §2.2).
  EXPECT_EQ(StatusOf(RawExchange(server_->port(), "\r\n\r\nGET /api/v1/health HTTP/1.1\r\n\r\n")), 200);
}

}  // namespace
}  // namespace fesbench::testing
