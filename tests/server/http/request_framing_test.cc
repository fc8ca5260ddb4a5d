// Unit: request framing (request_framing.h) — where one request ends, and
// which heads are refused before reaching a handler.

#include "server/http/request_framing.h"

#include <gtest/gtest.h>

namespace fesbench::server::http {
namespace {

using State = Framing::State;

Framing Frame(std::string_view bytes) { return FrameRequest(bytes, FramingLimits{}); }

TEST(RequestFramingTest, CompleteIncompleteAndPipelined) {
  const std::string get = "GET /api/v1/health HTTP/1.1\r\nHost: x\r\n\r\n";
  auto f = Frame(get);
  EXPECT_EQ(f.state, State::kComplete);
  EXPECT_EQ(f.total(), get.size());
  EXPECT_EQ(f.method, "GET");
  EXPECT_EQ(f.path, "/api/v1/health");
  EXPECT_TRUE(f.keep_alive);
  // Every prefix is incomplete, never an error.
  for (std::size_t n = 0; n < get.size(); ++n) {
    EXPECT_EQ(Frame(get.substr(0, n)).state, State::kIncomplete) << n;
  }
  EXPECT_EQ(Frame(get + get).total(), get.size());
  const std::string post = "POST /a?x=1 HTTP/1.1\r\ncontent-length: 4\r\n\r\n{}{}";
  const std::string pipelined = post + "GET";  // (the framing's views point into it)
  f = Frame(pipelined);
  EXPECT_EQ(f.state, State::kComplete);
  EXPECT_EQ(f.total(), post.size());
  EXPECT_EQ(f.path, "/a");
  f = Frame(post.substr(0, post.size() - 1));
  EXPECT_EQ(f.state, State::kIncomplete);
  EXPECT_TRUE(f.head_complete);
  f = Frame("\r\n\r\n" + get);
  EXPECT_EQ(f.state, State::kComplete);
  EXPECT_EQ(f.skip, 4u);
}

TEST(RequestFramingTest, ConnectionExpectAndAbsoluteForm) {
  EXPECT_FALSE(Frame("GET / HTTP/1.1\r\nConnection: Close\r\n\r\n").keep_alive);
  EXPECT_FALSE(Frame("GET / HTTP/1.0\r\n\r\n").keep_alive);
  EXPECT_TRUE(Frame("GET / HTTP/1.0\r\nConnection: keep-alive\r\n\r\n").keep_alive);
  EXPECT_TRUE(Frame("POST / HTTP/1.1\r\nExpect: 100-continue\r\nContent-Length: 3\r\n\r\n")
                  .expect_continue);
  EXPECT_EQ(Frame("GET http://h:1/api/v1/health?x HTTP/1.1\r\n\r\n").path, "/api/v1/health");
  EXPECT_EQ(Frame("GET HTTPS://h HTTP/1.1\r\n\r\n").path, "/");
}

TEST(RequestFramingTest, TheHeadersJudgedBeforeTheBody) {
  const std::string head =
      "POST /api/v1/sessions/3/trials HTTP/1.1\r\nauthorization:  Bearer fsb_x \r\n"
      "Content-Type: application/zip\r\nContent-Length: 9\r\n\r\n";
  const Framing f = Frame(head);  // the body has not come yet
  EXPECT_EQ(f.state, State::kIncomplete);
  EXPECT_TRUE(f.head_complete);
  EXPECT_EQ(f.authorization, "Bearer fsb_x");
  EXPECT_EQ(f.content_type, "application/zip");
  EXPECT_TRUE(f.upload);
  EXPECT_TRUE(Frame("GET / HTTP/1.1\r\n\r\n").authorization.empty());
}

TEST(RequestFramingTest, Refusals) {
  const std::pair<std::string, int> cases[] = {
      {"POST / HTTP/1.1\r\nContent-Length: -1\r\n\r\n", 400},
      {"POST / HTTP/1.1\r\nContent-Length: 18446744073709551617\r\n\r\n", 413},
      {"POST / HTTP/1.1\r\nContent-Length: 2000000\r\n\r\n", 413},
      {"POST / HTTP/1.1\r\nContent-Length: 1\r\nContent-Length: 2\r\n\r\n", 400},
      {"POST / HTTP/1.1\r\nContent-Length: 1,1\r\n\r\n", 400},
      {"POST / HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n", 411},
      {"GET / HTTP/1.1\r\nContent-Length: 1\r\n\r\nx", 400},
      {"GET / HTTP/1.1\nHost: x\n\n", 400},
      {"GET / HTTP/1.1\rX", 400},
      {std::string("GET / HTTP/1.1\r\nX: \0\r\n\r\n", 24), 400},
      {"GET / HTTP/1.1\r\nX: a\r\n folded\r\n\r\n", 400},
      {"GET / HTTP/1.1\r\nBad Name: a\r\n\r\n", 400},
      {"GET / HTTP/2.0\r\n\r\n", 400},
      {"GET /\r\n\r\n", 400},
      {"GET  / HTTP/1.1\r\n\r\n", 400},
      {"G(T / HTTP/1.1\r\n\r\n", 400},
      {"GET /" + std::string(9000, 'a') + " HTTP/1.1\r\n\r\n", 414},
      {"GET /" + std::string(9000, 'a'), 414},
      {"GET / HTTP/1.1\r\nX: " + std::string(20000, 'a'), 431},
  };
  for (const auto& [bytes, status] : cases) {
    const auto f = Frame(bytes);
    EXPECT_EQ(f.state, State::kError) << bytes.substr(0, 60);
    EXPECT_EQ(f.error.http_status, status) << bytes.substr(0, 60);
  }
  std::string many = "GET / HTTP/1.1\r\n";
  for (int i = 0; i < 65; ++i) many += "X-" + std::to_string(i) + ": v\r\n";
  EXPECT_EQ(Frame(many + "\r\n").error.http_status, 431);
}

}  // namespace
}  // namespace fesbench::server::http
