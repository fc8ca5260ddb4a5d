// Integration, against a real server process: the e-stop is never refused
// for load (docs/SAFETY.md, "The e-stop under load"). While one address
// keeps 600 idle connections open, sends upload heads declaring 256 MiB
// with no token and no body (512 at a time), and presents 10 wrong tokens a
// second, a clinician's e-stop on a new connection from the same address is
// answered 200 every time. Latencies are printed and recorded; the bound
// asserted is generous (it fails on a refusal or on a wait for a deadline,
// not on a slow machine). Also: a token-less upload head is refused 401 at
// once without its body being read, and an upload head left without its
// body is closed by its deadline.

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <thread>

#include "server_process.h"

namespace fesbench::testing {
namespace {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

const std::string kUploadHead =
    "POST /api/v1/sessions/1/trials HTTP/1.1\r\nHost: x\r\nContent-Type: application/zip\r\n"
    "Content-Length: 268435456\r\n\r\n";

// Keeps `count` connections of one kind open, replacing those the server
// closed, until stopped; counts how many it opened.
class Crowd {
 public:
  Crowd(int port, int count, std::string first_bytes)
      : port_(port), count_(count), bytes_(std::move(first_bytes)), thread_([this] { Loop(); }) {}
  ~Crowd() {
    stop_.store(true);
    thread_.join();
  }
  int opened() const { return opened_.load(); }

 private:
  void Loop() {
    std::vector<std::unique_ptr<RawConnection>> held;
    while (!stop_.load()) {
      held.erase(std::remove_if(held.begin(), held.end(),
                                [](const auto& c) { return c->ClosedByPeer(); }),
                 held.end());
      while (static_cast<int>(held.size()) < count_ && !stop_.load()) {
        auto c = std::make_unique<RawConnection>(port_);
        if (!c->ok()) break;
        if (!bytes_.empty()) c->Send(bytes_);
        held.push_back(std::move(c));
        ++opened_;
      }
      std::this_thread::sleep_for(milliseconds(200));
    }
  }

  int port_;
  int count_;
  std::string bytes_;
  std::atomic<bool> stop_{false};
  std::atomic<int> opened_{0};
  std::thread thread_;
};

TEST(EStopUnderPressureTest, AnsweredEveryTimeWhileIdleConnectionsUploadHeadsAndWrongTokensFlood) {
  ServerProcess server;
  auto client = server.Client();
  const std::string clinician = CreateUserToken(client, server.admin_token(), "cli", "clinician");

  Crowd idle(server.port(), 600, "");
  Crowd uploads(server.port(), 512, kUploadHead);
  std::atomic<bool> flooding{true};
  const auto flood_start = Clock::now();
  std::atomic<int> wrong_sent{0}, wrong_429{0};
  std::thread flood([&] {
    while (flooding.load()) {
      const std::string answer = RawExchange(
          server.port(),
          "GET /api/v1/subjects HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer fsb_" +
              std::string(64, '0') + "\r\nConnection: close\r\n\r\n",
          milliseconds(2000));
      ++wrong_sent;
      wrong_429 += RawStatus(answer) == 429 ? 1 : 0;
      std::this_thread::sleep_for(milliseconds(100));
    }
  });
  std::this_thread::sleep_for(milliseconds(1500));  // the crowd in place

  constexpr int kPresses = 40;
  std::vector<double> latencies;
  int answered = 0;
  for (int k = 0; k < kPresses; ++k) {
    const auto start = Clock::now();
    RawConnection press(server.port());
    ASSERT_TRUE(press.ok());
    press.Send("POST /api/v1/bench/estop HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer " +
               clinician + "\r\nContent-Length: 0\r\n\r\n");
    const std::string answer = press.ReadUntil(
        [](const std::string& r) { return CountResponses(r) >= 1; }, milliseconds(5000));
    latencies.push_back(MsSince(start));
    if (RawStatus(answer) == 200) {
      ++answered;
    } else {
      ADD_FAILURE() << "press " << k << ": " << answer.substr(0, 300);
    }
    std::this_thread::sleep_for(milliseconds(100));
  }
  flooding.store(false);
  flood.join();
  const double flood_s = MsSince(flood_start) / 1000.0;

  std::sort(latencies.begin(), latencies.end());
  const double p50 = latencies[latencies.size() / 2];
  const double p99 = latencies[std::min(latencies.size() - 1, latencies.size() * 99 / 100)];
  std::cout << "e-stop under pressure: " << answered << "/" << kPresses << " answered 200; p50 "
            << p50 << " ms, p99 " << p99 << " ms, max " << latencies.back() << " ms; idle "
            << "connections opened " << idle.opened() << ", upload heads " << uploads.opened()
            << ", wrong tokens " << wrong_sent.load() << " (" << wrong_429.load() << " slowed 429)"
            << std::endl;
  ::testing::Test::RecordProperty("estop_p50_ms", std::to_string(p50));
  ::testing::Test::RecordProperty("estop_p99_ms", std::to_string(p99));
  EXPECT_EQ(answered, kPresses);
  // Generous (sanitizer builds run this too): a press that waited for any
  // deadline (≥ 3 s) fails it.
  EXPECT_LT(latencies.back(), 2000.0);
  // The throttle (a bucket of 30 failures refilling 1 a second, the
  // server's default) must have engaged once the flood outran it; a server
  // slowed so far (a sanitizer on a loaded machine) that the flood never
  // outran the refill owes no 429.
  if (wrong_sent.load() > 30 + flood_s * 1.0 + 5) {
    EXPECT_GT(wrong_429.load(), 0) << "the wrong tokens were slowed down (" << wrong_sent.load()
                                   << " in " << flood_s << " s)";
  }
  EXPECT_EQ(Call(client, "GET", "/api/v1/health", "").status, 200);
}

TEST(EStopUnderPressureTest, AnUploadHeadWithoutATokenIsRefusedBeforeItsBody) {
  ServerProcess server;
  RawConnection c(server.port());
  const auto start = Clock::now();
  ASSERT_TRUE(c.Send(kUploadHead));  // 256 MiB declared, none sent
  const std::string answer =
      c.ReadUntil([](const std::string& r) { return CountResponses(r) >= 1; }, milliseconds(3000));
  const double ms = MsSince(start);
  EXPECT_EQ(RawStatus(answer), 401) << answer;
  EXPECT_NE(answer.find("WWW-Authenticate: Bearer"), std::string::npos) << answer;
  EXPECT_NE(answer.find("Connection: close"), std::string::npos) << answer;
  EXPECT_LT(ms, 1000.0) << "answered from the head, not after a body";
  std::cout << "token-less upload head: 401 after " << ms << " ms" << std::endl;

  // 100 Continue only for an admitted request: a wrong token gets none.
  RawConnection expect(server.port());
  ASSERT_TRUE(expect.Send(
      "POST /api/v1/sessions/1/trials HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer fsb_" +
      std::string(64, '7') + "\r\nExpect: 100-continue\r\nContent-Length: 1000\r\n\r\n"));
  const std::string refused = expect.ReadUntil(
      [](const std::string& r) { return CountResponses(r) >= 1; }, milliseconds(3000));
  EXPECT_EQ(refused.find("100 Continue"), std::string::npos) << refused;
  EXPECT_EQ(RawStatus(refused), 401) << refused;
}

TEST(EStopUnderPressureTest, AnAdmittedUploadThatNeverSendsItsBodyIsClosedByItsDeadline) {
  ServerProcess server;
  RawConnection c(server.port());
  const auto start = Clock::now();
  ASSERT_TRUE(c.Send("POST /api/v1/sessions/1/trials HTTP/1.1\r\nHost: x\r\nAuthorization: "
                     "Bearer " + server.admin_token() +
                     "\r\nContent-Type: application/zip\r\nExpect: 100-continue\r\n"
                     "Content-Length: 268435456\r\n\r\n"));
  const std::string answer = c.ReadUntil(
      [](const std::string& r) { return r.find("HTTP/1.1 408") != std::string::npos; },
      milliseconds(15000));
  const double ms = MsSince(start);
  EXPECT_NE(answer.find("HTTP/1.1 100 Continue"), std::string::npos) << answer;
  EXPECT_NE(answer.find("HTTP/1.1 408"), std::string::npos) << answer;
  EXPECT_NE(answer.find("stalled"), std::string::npos) << answer;
  // request_timeout (5 s) without a byte of body, not 5 s + 1 s per MiB.
  EXPECT_LT(ms, 9000.0);
  std::cout << "upload head without its body: closed after " << ms << " ms" << std::endl;
}

}  // namespace
}  // namespace fesbench::testing
