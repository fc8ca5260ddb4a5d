// The ScienceMode2 stimulator driver against the RehaStim2 emulator over a
// real pseudo-terminal ("ScienceMode2 – Description and Protocol" v1.24:
// §3.5 connect, §4.3 channel list mode, §2.3 timeouts, §5.2 errors).

#include "server/bench/sciencemode2_stimulator.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <thread>

#include "server/bench/emulator/sciencemode2_emulator.h"
#include "tests/server/wait_until.h"

namespace fesbench::server::sciencemode2 {
namespace {

// The amplitude a SinglePulse delivered, nullopt if it was refused.
std::optional<double> Delivered(const api::Result<double>& r) {
  return r.ok() ? std::optional<double>(*r) : std::nullopt;
}

using namespace std::chrono_literals;

StimulatorConfig ConfigFor(const Emulator& emulator) {
  StimulatorConfig c;
  c.port_path = emulator.port_path();
  c.channel = 2;
  c.session_max_ma = 60.0;
  c.reply_timeout = 150ms;
  return c;
}

TEST(ScienceMode2Stimulator, RampIsDeliveredWithinTheDeviceResolution) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Stimulator stim(ConfigFor(emulator));
  ASSERT_TRUE(stim.Connect().ok()) << stim.fault().ToString();
  // A 0 → 50 mA ramp in 0.7 mA steps; the device's step is 1 mA (§4.3),
  // and the driver rounds down: never more than commanded.
  std::vector<double> commanded;
  for (double ma = 0.0; ma <= 50.0; ma += 0.7) {
    ASSERT_TRUE(stim.SetAmplitude(ma).ok()) << stim.fault().ToString();
    EXPECT_EQ(stim.acknowledged_ma(), std::floor(ma + 1e-9));
    commanded.push_back(ma);
    ASSERT_TRUE(stim.KeepAlive().ok()) << stim.fault().ToString();
  }
  ASSERT_TRUE(stim.Stop().ok()) << stim.fault().ToString();
  const auto d = emulator.deliveries();
  ASSERT_EQ(d.size(), commanded.size() + 1);
  for (std::size_t i = 0; i < commanded.size(); ++i) {
    EXPECT_EQ(d[i].channel, 2);
    EXPECT_EQ(d[i].pulse_width_us, 300);
    EXPECT_LE(d[i].current_ma, commanded[i] + 1e-9) << i;
    EXPECT_GT(d[i].current_ma, commanded[i] - 1.0) << i;
  }
  EXPECT_TRUE(d.back().stop);
  EXPECT_EQ(stim.acknowledged_ma(), 0.0);
}

TEST(ScienceMode2Stimulator, RefusesAboveTheSessionMaximumAndStops) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Stimulator stim(ConfigFor(emulator));
  ASSERT_TRUE(stim.Connect().ok()) << stim.fault().ToString();
  ASSERT_TRUE(stim.SetAmplitude(30.0).ok());
  const api::Status refused = stim.SetAmplitude(61.0);
  EXPECT_EQ(refused.code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_EQ(refused.message(), stim.fault().message());  // the latched fault itself
  EXPECT_NE(stim.fault().message().find("outside 0–60"), std::string::npos)
      << stim.fault().ToString();
  std::this_thread::sleep_for(50ms);
  EXPECT_FALSE(emulator.stimulating());
  for (const auto& d : emulator.deliveries()) EXPECT_LE(d.current_ma, 60);
}

TEST(ScienceMode2Stimulator, EmergencyStopFromAnotherThreadStopsTheDeviceAndLatches) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Stimulator stim(ConfigFor(emulator));
  ASSERT_TRUE(stim.Connect().ok()) << stim.fault().ToString();
  ASSERT_TRUE(stim.SetAmplitude(20.0).ok());
  std::thread([&] { stim.EmergencyStop(); }).join();
  std::this_thread::sleep_for(50ms);
  EXPECT_FALSE(emulator.stimulating());
  EXPECT_TRUE(emulator.deliveries().back().stop);
  EXPECT_TRUE(stim.estopped());
  EXPECT_FALSE(stim.faulted());
  EXPECT_EQ(stim.acknowledged_ma(), 0.0);
  // Latched: nothing stimulating is sent; zero is accepted.
  const std::size_t sent = emulator.deliveries().size();
  EXPECT_EQ(stim.SetAmplitude(5.0).code(), api::ErrorCode::kConflict);  // not a fault
  EXPECT_TRUE(stim.fault().ok());
  EXPECT_TRUE(stim.SetAmplitude(0.0).ok());
  EXPECT_TRUE(stim.KeepAlive().ok());  // the stop's ack is read and ignored
  EXPECT_EQ(emulator.deliveries().size(), sent);
  // Cleared: channel-list mode is initialised again, then started.
  stim.ClearEStop();
  ASSERT_TRUE(stim.SetAmplitude(7.0).ok()) << stim.fault().ToString();
  std::this_thread::sleep_for(20ms);
  EXPECT_TRUE(emulator.stimulating());
  EXPECT_EQ(emulator.deliveries().back().current_ma, 7);
  EXPECT_TRUE(stim.Stop().ok()) << stim.fault().ToString();
}

TEST(ScienceMode2Stimulator, SinglePulseStopsTheTrainFirstAndIsRoundedDown) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Stimulator stim(ConfigFor(emulator));
  ASSERT_TRUE(stim.Connect().ok()) << stim.fault().ToString();
  ASSERT_TRUE(stim.SetAmplitude(20.0).ok());
  EXPECT_EQ(Delivered(stim.SinglePulse(33.7)), std::optional<double>(33.0))
      << stim.fault().ToString();
  const auto d = emulator.deliveries();
  ASSERT_EQ(d.size(), 3u);
  EXPECT_TRUE(d[1].stop);  // the train stopped, then the pulse
  EXPECT_EQ(d[2].reason, "single");
  EXPECT_EQ(d[2].channel, 2);
  EXPECT_EQ(d[2].current_ma, 33);
  EXPECT_EQ(d[2].pulse_width_us, 300);
  // The train starts again (channel-list mode initialised again).
  ASSERT_TRUE(stim.SetAmplitude(10.0).ok()) << stim.fault().ToString();
  EXPECT_EQ(emulator.deliveries().back().current_ma, 10);
  // Above the session maximum: refused without sending, a fault.
  EXPECT_FALSE(stim.SinglePulse(61.0).ok());
  EXPECT_NE(stim.fault().message().find("outside 0–60"), std::string::npos)
      << stim.fault().ToString();
}

TEST(ScienceMode2Stimulator, FaultStopsTheDevice) {
  // The bench e-stop path: Fault() sends StopChannelListMode at once.
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Stimulator stim(ConfigFor(emulator));
  ASSERT_TRUE(stim.Connect().ok()) << stim.fault().ToString();
  ASSERT_TRUE(stim.SetAmplitude(20.0).ok());
  (void)stim.Fault(api::Status::Unavailable("bench e-stop"));
  std::this_thread::sleep_for(50ms);
  EXPECT_FALSE(emulator.stimulating());
  EXPECT_EQ(emulator.deliveries().back().reason, "command");
  EXPECT_EQ(stim.fault().message(), "bench e-stop");
  EXPECT_FALSE(stim.SetAmplitude(5.0).ok());  // latched
}

TEST(ScienceMode2Stimulator, LostDeviceIsAFaultNamingTheCable) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Stimulator stim(ConfigFor(emulator));
  ASSERT_TRUE(stim.Connect().ok()) << stim.fault().ToString();
  ASSERT_TRUE(stim.SetAmplitude(20.0).ok());
  emulator.Unplug();
  EXPECT_FALSE(stim.SetAmplitude(21.0).ok() && stim.KeepAlive().ok());
  EXPECT_NE(stim.fault().message().find("stimulator lost"), std::string::npos)
      << stim.fault().ToString();
  EXPECT_EQ(stim.acknowledged_ma(), 0.0);
}

TEST(ScienceMode2Stimulator, GarbledReplyIsAFaultNamingTheChecksum) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Stimulator stim(ConfigFor(emulator));
  ASSERT_TRUE(stim.Connect().ok()) << stim.fault().ToString();
  emulator.set_fault(EmulatorFault::kCorruptReplies);
  EXPECT_FALSE(stim.SetAmplitude(20.0).ok());
  EXPECT_EQ(stim.fault().message(), "stimulator reply garbled: checksum error");
}

TEST(ScienceMode2Stimulator, SilenceIsATimeout) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Stimulator stim(ConfigFor(emulator));
  ASSERT_TRUE(stim.Connect().ok()) << stim.fault().ToString();
  emulator.set_fault(EmulatorFault::kSilent);
  EXPECT_FALSE(stim.SetAmplitude(20.0).ok());
  EXPECT_EQ(stim.fault().code(), api::ErrorCode::kUnavailable);
  EXPECT_EQ(stim.fault().message(), "stimulator timeout: no reply within 150 ms");
}

// A device that goes silent, restarts, or stops on its own while the driver
// sends nothing (a constant train: only the keeper thread's status queries)
// is noticed within one status period: status_interval 200 ms + keeper tick
// 50 ms + reply_timeout 200 ms, the defaults. Measured from the fault to the
// driver's fault, which writes StopChannelListMode before it latches.
TEST(ScienceMode2Stimulator, ASilentResetOrStoppedDeviceIsNoticedWithinHalfASecond) {
  struct Case {
    EmulatorFault fault;
    const char* reason;
  };
  const Case cases[] = {{EmulatorFault::kSilent, "stimulator timeout: no reply within 200 ms"},
                        {EmulatorFault::kReset, "reset"},
                        {EmulatorFault::kWrongMode,
                         "stimulator in start mode where the driver set channel list running"}};
  double worst_ms = 0;
  for (const Case& c : cases) {
    for (const auto phase : {0ms, 90ms, 170ms}) {  // where in the status period the fault falls
      auto opened = Emulator::Open();
      ASSERT_TRUE(opened.ok()) << opened.status().ToString();
      Emulator& emulator = **opened;
      StimulatorConfig config;  // the defaults, as the server uses them
      config.port_path = emulator.port_path();
      config.session_max_ma = 60.0;
      Stimulator stim(config);
      ASSERT_TRUE(stim.Connect().ok()) << stim.fault().ToString();
      ASSERT_TRUE(stim.SetAmplitude(20.0).ok()) << stim.fault().ToString();
      std::this_thread::sleep_for(phase);
      emulator.set_fault(c.fault);
      const double ms = test::MsUntil([&] { return stim.faulted(); });
      ASSERT_TRUE(stim.faulted()) << c.reason;
      EXPECT_NE(stim.fault().message().find(c.reason), std::string::npos)
          << stim.fault().ToString();
      EXPECT_EQ(stim.acknowledged_ma(), 0.0);
      std::this_thread::sleep_for(20ms);
      EXPECT_FALSE(emulator.stimulating()) << c.reason;
      worst_ms = std::max(worst_ms, ms);
      std::cout << "[ figure ] ScienceMode2 " << c.reason << ", phase " << phase.count()
                << " ms: noticed in " << ms << " ms\n";
    }
  }
#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
  EXPECT_LE(worst_ms, 500.0);  // one status period; a sanitizer's slowdown is not the driver's
#endif
}

TEST(ScienceMode2Stimulator, ThePortHasTheDescriptionsSettings) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Stimulator stim(ConfigFor(emulator));
  ASSERT_TRUE(stim.Connect().ok()) << stim.fault().ToString();
  const SerialSettings s = stim.port_settings();  // tcgetattr on the open port
  EXPECT_EQ(s.baud, 460800);  // §2.1 Table 4 (its even parity a pty cannot keep)
  EXPECT_TRUE(ScienceMode2Settings().even_parity);
  EXPECT_EQ(s.stop_bits, 1);
  EXPECT_FALSE(s.rts_cts);
}

TEST(ScienceMode2Stimulator, WatchdogKeepsTheDeviceStimulating) {
  // §2.3: without traffic the device stops after 1200 ms; the status query
  // (GetStimulationMode every 200 ms) is traffic.
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Stimulator stim(ConfigFor(emulator));
  ASSERT_TRUE(stim.Connect().ok()) << stim.fault().ToString();
  ASSERT_TRUE(stim.SetAmplitude(10.0).ok());
  const auto end = std::chrono::steady_clock::now() + 1600ms;
  while (std::chrono::steady_clock::now() < end) {
    ASSERT_TRUE(stim.KeepAlive().ok()) << stim.fault().ToString();
    std::this_thread::sleep_for(30ms);
  }
  EXPECT_TRUE(emulator.stimulating());
  EXPECT_TRUE(stim.Stop().ok());
}

}  // namespace
}  // namespace fesbench::server::sciencemode2
