// The test helper itself: a server that ends badly at shutdown (a crash, or a
// sanitizer report, which exits non-zero or aborts) fails the test that
// started it, and a clean SIGTERM shutdown does not.

#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>
#include <signal.h>

#include "server_process.h"

namespace fesbench::testing {
namespace {

TEST(ServerProcessTest, ACleanShutdownPasses) {
  ServerProcess server;
  auto client = server.Client();
  EXPECT_EQ(Call(client, "GET", "/api/v1/health", "").status, 200);
}

TEST(ServerProcessTest, AServerKilledBeforeShutdownFailsTheTest) {
  EXPECT_NONFATAL_FAILURE(
      {
        ServerProcess server;
        ::kill(server.pid(), SIGABRT);  // what UBSan's halt_on_error does
      },
      "fesbench-server was killed by signal 6 at shutdown");
}

}  // namespace
}  // namespace fesbench::testing
