// Integration (README "A real stimulator", docs/SAFETY.md): fesbench-server
// processes with a RehaStim 2 emulated on a pseudo-terminal in this test.
// A hardware stimulator at a time scale other than 1 is refused at start
// naming the flag; a second server on the same port is refused naming the
// first server's process; the leg's pulse clock runs at the device's own
// rate; a device that restarts on its own latches the e-stop within one
// status period and GET /bench names it as the source.

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <thread>

#include "server/bench/emulator/sciencemode2_emulator.h"
#include "server_process.h"

namespace fesbench::testing {
namespace {

using Clock = std::chrono::steady_clock;
using server::sciencemode2::Emulator;
using server::sciencemode2::EmulatorFault;

std::vector<std::string> WithDevice(const Emulator& emulator, const std::string& time_scale) {
  return {"--stimulator", "sciencemode2", "--stimulator-port", emulator.port_path(),
          "--time-scale", time_scale};
}

TEST(StimulatorServer, TimeScaleOtherThanOneIsRefusedWithADevice) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  const auto dir = std::filesystem::temp_directory_path() /
                   ("fesbench_stimsrv_" + std::to_string(::getpid()));
  std::vector<std::string> args = {"--port", "0", "--db", (dir / "fesbench.db").string(),
                                   "--data-dir", dir.string(), "--dds-transport", "off"};
  for (const std::string& a : WithDevice(emulator, "0")) args.push_back(a);
  const ExitedServer refused = RunServerToExit(args);
  std::filesystem::remove_all(dir);
  EXPECT_NE(refused.exit_code, 0) << refused.output;
  EXPECT_NE(refused.error.find("time-scale"), std::string::npos) << refused.error;
  EXPECT_NE(refused.error.find("--stimulator sciencemode2"), std::string::npos) << refused.error;
  EXPECT_EQ(refused.output.find("listening"), std::string::npos) << refused.output;
  EXPECT_FALSE(emulator.connected()) << "refused before the device was touched";
}

TEST(StimulatorServer, ASecondServerOnThePortIsRefusedAndADeviceResetIsTheEStopsSource) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  ServerProcess first(WithDevice(emulator, "1"));
  auto client = first.Client();
  const std::string admin = first.admin_token();
  auto bench = Call(client, "GET", "/api/v1/bench", admin);
  ASSERT_EQ(bench.status, 200) << bench.text;
  EXPECT_EQ(bench.body["kind"], "sciencemode2+sim");
  // The leg's pulse clock runs at the device's own rate: 30.5 ms (§4.3).
  EXPECT_NEAR(bench.body["limits"]["pulse_rate_hz"].get<double>(), 1000.0 / 30.5, 1e-9);
  EXPECT_EQ(bench.body["estopped"], false);
  EXPECT_TRUE(emulator.connected());

  // The port is this server's: a second one is refused naming it.
  const auto dir = first.dir() / "second";
  std::vector<std::string> args = {"--port", "0", "--db", (dir / "fesbench.db").string(),
                                   "--data-dir", dir.string(), "--dds-transport", "off"};
  for (const std::string& a : WithDevice(emulator, "1")) args.push_back(a);
  const ExitedServer second = RunServerToExit(args);
  EXPECT_NE(second.exit_code, 0) << second.output;
  EXPECT_NE(second.error.find("in use by process " + std::to_string(first.pid()) +
                              " (fesbench-server)"),
            std::string::npos)
      << second.error;

  // The device restarts on its own: noticed, latched, named.
  const auto t0 = Clock::now();
  emulator.set_fault(EmulatorFault::kReset);
  std::string source;
  while (Clock::now() - t0 < std::chrono::seconds(5)) {
    bench = Call(client, "GET", "/api/v1/bench", admin);
    if (bench.body.value("estopped", false)) {
      source = bench.body["state"].value("estop_source", "");
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  std::printf("device reset seen by GET /bench after %.0f ms\n", MsSince(t0));
  EXPECT_EQ(bench.body["estopped"], true) << bench.text;
  EXPECT_NE(source.find("sciencemode2 stimulator reset"), std::string::npos) << bench.text;
  EXPECT_EQ(first.Terminate(), 0) << first.Stderr();
}

}  // namespace
}  // namespace fesbench::testing
