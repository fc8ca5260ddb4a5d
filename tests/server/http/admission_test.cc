// Integration: admission beyond the server's limits, against a real server
// process: an event stream beyond --max-streams is answered 503 with
// Retry-After, at once; a connection beyond the per-address (256) or open
// (512) connection limit is never refused: the oldest idle connection is
// closed to make room, so the newest client is served.

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "server_process.h"

namespace fesbench::testing {
namespace {

using std::chrono::milliseconds;

bool HeadersDone(const std::string& r) { return r.find("\r\n\r\n") != std::string::npos; }

TEST(AdmissionTest, AStreamBeyondMaxStreamsIs503WithRetryAfterAndTheFirstKeepsFlowing) {
  ServerProcess server({"--time-scale", "1", "--max-streams", "1"});
  auto client = server.Client();
  const std::string token = server.admin_token();
  auto subject =
      Call(client, "POST", "/api/v1/subjects", token, {{"code", "ADM-01"}, {"legs", {"right"}}});
  ASSERT_EQ(subject.status, 201) << subject.text;
  auto session =
      Call(client, "POST",
           "/api/v1/subjects/" + std::to_string(subject.body["id"].get<int>()) + "/sessions", token,
           {{"leg", "right"}, {"date", "2026-11-24"}});
  ASSERT_EQ(session.status, 201) << session.text;
  auto run = Call(client, "POST",
                  "/api/v1/sessions/" + std::to_string(session.body["id"].get<int>()) + "/runs",
                  token, {{"protocol", "tolerance_test"}});
  ASSERT_EQ(run.status, 201) << run.text;
  const std::string run_path = "/api/v1/runs/" + std::to_string(run.body["run_id"].get<int>());
  std::atomic<bool> beating{true};
  std::thread heart([&] {
    auto hc = server.Client();
    while (beating.load()) {
      Call(hc, "POST", run_path + "/heartbeat", token);
      std::this_thread::sleep_for(milliseconds(200));
    }
  });

  const std::string request = "GET " + run_path +
                              "/stream HTTP/1.1\r\nHost: t\r\nAuthorization: Bearer " + token +
                              "\r\n\r\n";
  RawConnection first(server.port());
  ASSERT_TRUE(first.Send(request));
  const std::string open = first.ReadUntil(HeadersDone, milliseconds(5000));
  EXPECT_EQ(RawStatus(open), 200) << open;

  RawConnection second(server.port());
  ASSERT_TRUE(second.Send(request));
  const std::string refused = second.ReadUntil(
      [](const std::string& r) { return CountResponses(r) >= 1; }, milliseconds(5000));
  EXPECT_EQ(RawStatus(refused), 503) << refused;
  EXPECT_NE(refused.find("Retry-After:"), std::string::npos) << refused;
  EXPECT_NE(refused.find("too many open event streams"), std::string::npos) << refused;

  // The first stream still delivers events; health answers.
  const std::string more = first.ReadUntil(
      [](const std::string& r) { return r.find("event: samples") != std::string::npos; },
      milliseconds(5000));
  EXPECT_NE(more.find("event: samples"), std::string::npos);
  EXPECT_EQ(Call(client, "GET", "/api/v1/health", "").status, 200);

  beating.store(false);
  heart.join();
  EXPECT_EQ(Call(client, "POST", run_path + "/cancel", token).status, 200);
  EXPECT_EQ(server.Terminate(), 0);
}

TEST(AdmissionTest, AConnectionBeyondTheLimitsClosesTheOldestIdleOneAndIsServed) {
  ServerProcess server;
  constexpr int kPerAddress = 256;  // HttpServerOptions::max_connections_per_address
  constexpr int kOpened = kPerAddress + 44;
  std::vector<std::unique_ptr<RawConnection>> held;
  for (int i = 0; i < kOpened; ++i) {
    held.push_back(std::make_unique<RawConnection>(server.port()));
    ASSERT_TRUE(held.back()->ok()) << i;
    // One answered request each: the server has accepted the connection,
    // which then idles in keep-alive.
    ASSERT_TRUE(held.back()->Send("GET /api/v1/health HTTP/1.1\r\nHost: localhost\r\n\r\n"));
    const std::string answer = held.back()->ReadUntil(
        [](const std::string& r) { return CountResponses(r) >= 1; }, milliseconds(5000));
    ASSERT_EQ(RawStatus(answer), 200) << i << ": " << answer;
  }
  // Every connection was served; the oldest idle ones made room for the
  // newest, which stay open.
  int closed_oldest = 0, open_newest = 0;
  for (int i = 0; i < kOpened - kPerAddress; ++i) closed_oldest += held[i]->ClosedByPeer() ? 1 : 0;
  for (int i = kOpened - kPerAddress; i < kOpened; ++i) {
    open_newest += held[i]->ClosedByPeer() ? 0 : 1;
  }
  EXPECT_EQ(closed_oldest, kOpened - kPerAddress);
  EXPECT_EQ(open_newest, kPerAddress);

  // One more client on a full table: an e-stop goes through at once.
  RawConnection estop(server.port());
  ASSERT_TRUE(estop.Send("POST /api/v1/bench/estop HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer " +
                         server.admin_token() + "\r\nContent-Length: 0\r\n\r\n"));
  const std::string answer = estop.ReadUntil(
      [](const std::string& r) { return CountResponses(r) >= 1; }, milliseconds(5000));
  EXPECT_EQ(RawStatus(answer), 200) << answer;
  held.clear();
  EXPECT_EQ(server.Terminate(), 0);
}

}  // namespace
}  // namespace fesbench::testing
