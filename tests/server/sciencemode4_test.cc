// ScienceMode4 (P24, low level): the packet layer byte for byte, as the
// public ScienceMode4 C library builds packets (smpt_packet_internal.c:
// smpt_insert_header, smpt_insert_cmd_number, smpt_compute_checksum;
// smpt_ll_packet_client.c: insert_ll_channel_config, smpt_insert_ll_point;
// the expected bytes below were worked out by hand from those functions),
// then the driver and a composed bench against the emulator over a real
// pseudo-terminal.

#include <gtest/gtest.h>

#include <algorithm>
#include <iostream>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string_view>
#include <thread>

#include "server/bench/composed_bench.h"
#include "server/bench/emulator/sciencemode4_emulator.h"
#include "server/bench/sciencemode4_packet.h"
#include "server/bench/sciencemode4_stimulator.h"
#include "server/bench/simulated_bench.h"
#include "server/bench/virtual_subject.h"
#include "server/protocols/plan.h"
#include "server/protocols/runner.h"
#include "tests/server/wait_until.h"

namespace fesbench::server::sciencemode4 {
namespace {

// The amplitude a SinglePulse delivered, nullopt if it was refused.
std::optional<double> Delivered(const api::Result<double>& r) {
  return r.ok() ? std::optional<double>(*r) : std::nullopt;
}

using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;

TEST(ScienceMode4Packet, Crc16IsCcittXmodem) {
  // CRC-16/XMODEM's check value.
  constexpr std::string_view kCheck = "123456789";
  EXPECT_EQ(Crc16(std::span(reinterpret_cast<const std::uint8_t*>(kCheck.data()), kCheck.size())),
            0x31C3);
}

TEST(ScienceMode4Packet, LlStopByteForByte) {
  // Packet number 1, command 4: bytes 9–10 = 1 << 2, 4; length 12 = 0x000C;
  // CRC-16 of {0x04, 0x04} = 0x8C40; header bytes stuffed (^ 0x55).
  EXPECT_EQ(BuildLlStop(1),
            (Bytes{0xF0, 0x81, 0x55, 0x81, 0x59, 0x81, 0xD9, 0x81, 0x15, 0x04, 0x04, 0x0F}));
}

TEST(ScienceMode4Packet, GetStimStatusByteForByteAndItsAck) {
  // Smpt_Cmd_Get_Stim_Status = 62 (smpt_definitions_data_types.h), no data:
  // bytes 9–10 = 1 << 2 | 62 >> 8, 62 & 0xFF; CRC-16 of {0x04, 0x3E} = 0x1B59.
  EXPECT_EQ(BuildGetStimStatus(1),
            (Bytes{0xF0, 0x81, 0x55, 0x81, 0x59, 0x81, 0x4E, 0x81, 0x0C, 0x04, 0x3E, 0x0F}));
  // The ack (insert_get_stim_status_ack): result, stim status, high voltage.
  const auto ack = DecodePacket(
      BuildGetStimStatusAck(5, Result::kSuccessful, StimStatus::kLlInitialized, 0));
  ASSERT_TRUE(ack.packet);
  EXPECT_EQ(ack.packet->command, 63);
  EXPECT_EQ(ack.packet->packet_number, 5);
  EXPECT_EQ(ack.packet->data, (Bytes{0x00, 0x01, 0x00}));
  EXPECT_EQ(StimStatusName(0), "uninitialised");
  EXPECT_EQ(StimStatusName(9), "status 9");
}

TEST(ScienceMode4Packet, LlChannelConfigByteForByte) {
  // A biphasic pulse on channel 1 (blue), connector 0: +20 mA for 300 µs,
  // 0 mA for 100 µs, −20 mA for 300 µs. First data byte: enable (0x80) |
  // channel << 5 (0x20) | points − 1 (2) = 0xA2; each point: time >> 4,
  // time << 4 | code >> 6, code << 2, interpolation << 5, with code = 2·I + 300.
  const Point points[] = {{300, 20.0}, {100, 0.0}, {300, -20.0}};
  EXPECT_EQ(*BuildLlChannelConfig(2, 1, 0, points),
            (Bytes{0xF0, 0x81, 0x55, 0x81, 0x4C, 0x81, 0x6D, 0x81, 0x5D, 0x08, 0x02, 0xA2, 0x12,
                   0xC5, 0x50, 0x00, 0x06, 0x44, 0xB0, 0x00, 0x12, 0xC4, 0x10, 0x00, 0x0F}));
  const DecodeResult r = DecodePacket(*BuildLlChannelConfig(2, 1, 0, points));
  ASSERT_TRUE(r.packet);
  EXPECT_EQ(r.packet->command, 2);
  const auto config = ParseLlChannelConfig(r.packet->data);
  ASSERT_TRUE(config);
  EXPECT_EQ(config->channel, 1);
  ASSERT_EQ(config->points.size(), 3u);
  EXPECT_EQ(config->points[2].time_us, 300);
  EXPECT_EQ(config->points[2].current_ma, -20.0);
  // Half-milliampere steps survive the coding.
  const Point half[] = {{250, 37.5}};
  EXPECT_EQ(ParseLlChannelConfig(DecodePacket(*BuildLlChannelConfig(0, 3, 1, half)).packet->data)
                ->points[0]
                .current_ma,
            37.5);
}

TEST(ScienceMode4Packet, ReservedBytesAreStuffedAndErrorsNamed) {
  // Packet number 60: byte 9 = 60 << 2 = 0xF0, a start byte: sent as 0x81 0xA5.
  const Bytes wire = *BuildLlInit(60);
  for (std::size_t i = 1; i + 1 < wire.size(); ++i) {
    EXPECT_NE(wire[i], 0xF0) << i;
    EXPECT_NE(wire[i], 0x0F) << i;
  }
  EXPECT_EQ(wire[9], 0x81);
  EXPECT_EQ(wire[10], 0xA5);
  const DecodeResult ok = DecodePacket(wire);
  ASSERT_TRUE(ok.packet);
  EXPECT_EQ(ok.packet->packet_number, 60);
  EXPECT_EQ(ok.packet->command, 0);
  Bytes bad_crc = wire;
  bad_crc[8] ^= 0x01;
  EXPECT_EQ(DecodePacket(bad_crc).error, DecodeError::kChecksum);
  Bytes bad_length = wire;
  bad_length[4] ^= 0x01;
  EXPECT_EQ(DecodePacket(bad_length).error, DecodeError::kLength);
  EXPECT_EQ(DecodePacket(Bytes{0xF0, 0x0F}).error, DecodeError::kFraming);
  const Point too_much[] = {{300, 150.5}};
  EXPECT_FALSE(BuildLlChannelConfig(0, 0, 0, too_much).ok());
  EXPECT_FALSE(BuildLlChannelConfig(0, 4, 0, too_much).ok());
}

StimulatorConfig ConfigFor(const Emulator& emulator) {
  StimulatorConfig c;
  c.port_path = emulator.port_path();
  c.channel = 2;
  c.session_max_ma = 60.0;
  c.reply_timeout = 150ms;
  return c;
}

TEST(ScienceMode4Stimulator, PulsesAreBiphasicRoundedDownAndRefusedAboveTheMaximum) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Stimulator stim(ConfigFor(emulator));
  ASSERT_TRUE(stim.Connect().ok()) << stim.fault().ToString();
  EXPECT_TRUE(emulator.initialised());
  EXPECT_EQ(Delivered(stim.SinglePulse(20.3)), std::optional<double>(20.0))
      << stim.fault().ToString();
  const auto d = emulator.deliveries();
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].channel, 2);
  ASSERT_EQ(d[0].points.size(), 3u);
  EXPECT_EQ(d[0].points[0].current_ma, 20.0);
  EXPECT_EQ(d[0].points[0].time_us, 300);
  EXPECT_EQ(d[0].points[1].current_ma, 0.0);
  EXPECT_EQ(d[0].points[2].current_ma, -20.0);
  // Above the session maximum: refused without sending, a fault.
  EXPECT_FALSE(stim.SinglePulse(61.0).ok());
  EXPECT_NE(stim.fault().message().find("outside 0–60"), std::string::npos)
      << stim.fault().ToString();
  // The pulse, then the fault's Ll_Stop once the emulator has read it.
  for (int i = 0; i < 100 && emulator.deliveries().size() < 2; ++i) std::this_thread::sleep_for(1ms);
  ASSERT_EQ(emulator.deliveries().size(), 2u);
  EXPECT_TRUE(emulator.deliveries().back().stop);
}

TEST(ScienceMode4Stimulator, EmergencyStopLatchesUntilCleared) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Stimulator stim(ConfigFor(emulator));
  ASSERT_TRUE(stim.Connect().ok()) << stim.fault().ToString();
  std::thread([&] { stim.EmergencyStop(); }).join();
  std::this_thread::sleep_for(30ms);
  EXPECT_FALSE(emulator.initialised());
  EXPECT_FALSE(stim.SinglePulse(10.0).ok());
  EXPECT_FALSE(stim.faulted());
  stim.ClearEStop();
  EXPECT_EQ(Delivered(stim.SinglePulse(10.0)), std::optional<double>(10.0))
      << stim.fault().ToString();  // Ll_Init again
  EXPECT_EQ(emulator.deliveries().back().current_ma(), 10.0);
}

TEST(ScienceMode4Stimulator, LostGarbledAndSilentDevicesAreNamedFaults) {
  {
    auto opened = Emulator::Open();
    ASSERT_TRUE(opened.ok()) << opened.status().ToString();
    Emulator& emulator = **opened;
    Stimulator stim(ConfigFor(emulator));
    ASSERT_TRUE(stim.Connect().ok());
    emulator.Unplug();
    EXPECT_FALSE(stim.SinglePulse(10.0).ok() && stim.Service().ok());
    EXPECT_NE(stim.fault().message().find("stimulator lost"), std::string::npos)
        << stim.fault().ToString();
  }
  {
    auto opened = Emulator::Open();
    ASSERT_TRUE(opened.ok()) << opened.status().ToString();
    Emulator& emulator = **opened;
    Stimulator stim(ConfigFor(emulator));
    ASSERT_TRUE(stim.Connect().ok());
    emulator.set_fault(EmulatorFault::kCorruptReplies);
    EXPECT_FALSE(stim.SinglePulse(10.0).ok());
    EXPECT_EQ(stim.fault().message(), "stimulator reply garbled: checksum error");
  }
  {
    auto opened = Emulator::Open();
    ASSERT_TRUE(opened.ok()) << opened.status().ToString();
    Emulator& emulator = **opened;
    Stimulator stim(ConfigFor(emulator));
    ASSERT_TRUE(stim.Connect().ok());
    emulator.set_fault(EmulatorFault::kSilent);
    EXPECT_FALSE(stim.SinglePulse(10.0).ok());
    EXPECT_EQ(stim.fault().message(), "stimulator timeout: no reply within 150 ms");
  }
}

// Between pulses (or runs) only the keeper thread's status queries go to
// the device: a silent, reset or stopped P24 is noticed within one status
// period (200 ms + 50 ms tick + 200 ms reply timeout, the defaults).
TEST(ScienceMode4Stimulator, ASilentResetOrStoppedDeviceIsNoticedWithinHalfASecond) {
  struct Case {
    EmulatorFault fault;
    const char* reason;
  };
  const Case cases[] = {
      {EmulatorFault::kSilent, "stimulator timeout: no reply within 200 ms"},
      {EmulatorFault::kReset, "stimulator uninitialised where the driver set low level initialised"},
      {EmulatorFault::kWrongMode,
       "stimulator uninitialised where the driver set low level initialised"}};
  double worst_ms = 0;
  for (const Case& c : cases) {
    for (const auto phase : {0ms, 90ms, 170ms}) {
      auto opened = Emulator::Open();
      ASSERT_TRUE(opened.ok()) << opened.status().ToString();
      Emulator& emulator = **opened;
      StimulatorConfig config;  // the defaults
      config.port_path = emulator.port_path();
      config.session_max_ma = 60.0;
      Stimulator stim(config);
      ASSERT_TRUE(stim.Connect().ok()) << stim.fault().ToString();
      ASSERT_EQ(Delivered(stim.SinglePulse(20.0)), std::optional<double>(20.0))
          << stim.fault().ToString();
      std::this_thread::sleep_for(phase);
      emulator.set_fault(c.fault);
      const double ms = test::MsUntil([&] { return stim.faulted(); });
      ASSERT_TRUE(stim.faulted()) << c.reason;
      EXPECT_NE(stim.fault().message().find(c.reason), std::string::npos)
          << stim.fault().ToString();
      EXPECT_FALSE(stim.SinglePulse(10.0).ok());
      worst_ms = std::max(worst_ms, ms);
      std::cout << "[ figure ] ScienceMode4 " << c.reason << ", phase " << phase.count()
                << " ms: noticed in " << ms << " ms\n";
    }
  }
#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
  EXPECT_LE(worst_ms, 500.0);
#endif
}

TEST(ScienceMode4Stimulator, ThePortHasTheLibrarysSettings) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  Stimulator stim(ConfigFor(emulator));
  ASSERT_TRUE(stim.Connect().ok()) << stim.fault().ToString();
  const SerialSettings s = stim.port_settings();  // tcgetattr on the open port
  EXPECT_EQ(s.baud, 3000000);  // smpt_serial_port.c: B3000000
  EXPECT_FALSE(s.even_parity);  // smpt_serial_port_linux.c: PARENB cleared, CSTOPB, CRTSCTS
  EXPECT_EQ(s.stop_bits, 2);
  EXPECT_TRUE(s.rts_cts);
}

TEST(ScienceMode4ComposedBench, EveryPulseTheLegReceivedWasSentToTheDevice) {
  auto opened = Emulator::Open();
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  Emulator& emulator = **opened;
  StimulatorConfig config;
  config.port_path = emulator.port_path();
  auto device = std::make_unique<Stimulator>(config);
  ASSERT_TRUE(device->Connect().ok()) << device->fault().ToString();
  const VirtualSubject subject = DrawVirtualSubject(7);
  ComposedBench bench(SimulatedBench::Create(subject).value(), std::move(device));
  EXPECT_EQ(bench.kind(), "sciencemode4+sim");
  protocols::SafetyEventLog log;
  SafeBench safe(bench, log.sink());
  protocols::SubjectContext ctx;
  ctx.threshold_ma = subject.threshold_ma;
  ctx.max_tolerated_ma = subject.max_tolerated_ma;
  ctx.min_angle_deg = 15.0;
  ctx.max_angle_deg = 108.0;
  ctx.inertia_kgm2 = subject.truth.passive.inertia_kgm2;
  auto plan = protocols::MakePlan("isometric_ramp_irc", {}, ctx);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  protocols::RunnerOptions options;
  options.arm_watchdog = false;
  protocols::ProtocolRunner runner(safe, &log, nullptr, options);
  const protocols::RunResult r = runner.Run(*plan, ctx);
  ASSERT_EQ(r.state, protocols::RunState::kDone) << r.reason;

  // The leg's pulses (every trial's read-back, grid and single) against
  // what the emulator recorded, in order: the same count, the same currents
  // (0.5 mA steps), each at most the session's maximum.
  std::vector<double> leg;
  for (const auto& rec : r.trials) {
    for (double ma : rec.trial.pulses->stim_ma) {
      if (ma > 0.0) leg.push_back(ma);
    }
  }
  std::vector<double> device_pulses;
  for (const auto& d : emulator.deliveries()) {
    if (!d.stop) device_pulses.push_back(d.current_ma());
  }
  ASSERT_GT(leg.size(), 100u);
  ASSERT_EQ(device_pulses.size(), leg.size());
  for (std::size_t i = 0; i < leg.size(); ++i) {
    EXPECT_EQ(device_pulses[i], leg[i]) << i;
    EXPECT_EQ(std::fmod(leg[i], 0.5), 0.0) << i;
    EXPECT_LE(leg[i], subject.max_tolerated_ma) << i;
  }
  EXPECT_FALSE(bench.HardwareEStopped());

  // Each trial's device log: one command per pulse the leg received, read
  // by the emulator within one device tick (the pulse period) of its logged time,
  // commanded = requested rounded down to 0.5 mA.
  const auto deliveries = emulator.deliveries();
  std::size_t logged = 0;
  double worst_ms = 0.0;
  std::size_t next = 0;  // host-paced: the log and the device's record are in one order
  for (const auto& rec : r.trials) {
    ASSERT_TRUE(rec.trial.device_commands);
    const api::DeviceCommandLog& log = *rec.trial.device_commands;
    EXPECT_EQ(log.device, "sciencemode4");
    EXPECT_EQ(log.current_step_ma, 0.5);
    EXPECT_DOUBLE_EQ(log.pulse_rate_hz, rec.trial.pulses->pulse_rate_hz);  // the host's clock
    for (std::size_t k = 0; k < log.size(); ++k) {
      EXPECT_EQ(log.commanded_ma[k], std::floor(log.requested_ma[k] / 0.5 + 1e-9) * 0.5) << k;
      const auto at = log.start_monotonic_ns + static_cast<std::int64_t>(log.t_s[k] * 1e9);
      while (next < deliveries.size() &&
             (deliveries[next].stop || deliveries[next].steady_ns < at - 1000)) {
        ++next;
      }
      ASSERT_LT(next, deliveries.size()) << k;
      EXPECT_EQ(deliveries[next].current_ma(), log.commanded_ma[k]) << k;
      const double late_ms = (deliveries[next].steady_ns - at) / 1e6;
      EXPECT_LE(late_ms, 1000.0 / log.pulse_rate_hz) << k;
      worst_ms = std::max(worst_ms, late_ms);
      ++next;
      ++logged;
    }
  }
  std::printf("[ figure ] P24: %zu pulse commands logged, read by the device at most %.3f ms "
              "after their logged time\n",
              logged, worst_ms);
  EXPECT_EQ(logged, leg.size());
}

}  // namespace
}  // namespace fesbench::server::sciencemode4
