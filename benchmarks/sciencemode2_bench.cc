// ScienceMode2 pulse-update latency (README, "A real stimulator").
// BM_CommandToWire/2 and /4: one StartChannelListMode (ScienceMode2) or
// Ll_Channel_Config (ScienceMode4) packet encoded and written to the serial
// port (termios, raw, the device's settings) until its last byte is
// readable at the far end of a pseudo-terminal, p50 and p99 as counters —
// the command-to-wire time on this host, without
// the USB-serial chip (the description §2.1 asks for the FTDI latency timer
// at 1 ms, which adds up to 1 ms on real hardware).
// BM_AcknowledgedUpdate: Stimulator::SetAmplitude against the emulator, the
// update plus its StartChannelListModeAck round trip.
// BM_EStopToDevice: the bench e-stop (ComposedBench::HardwareEStop, called
// on another thread than the control loop) until the emulator has stopped
// stimulating (it polls its pty every ≤ 5 ms while idle, so this is an upper
// bound of the driver's share).
// BM_Sm4PulseAcknowledged: one ScienceMode4 low-level pulse
// (Ll_Channel_Config, biphasic) against the P24 emulator, with its ack: the
// host-paced device's cost per pulse.

#include <benchmark/benchmark.h>
#include <fcntl.h>
#include <poll.h>
#include <stdlib.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <thread>
#include <vector>

#include "server/bench/composed_bench.h"
#include "server/bench/emulator/sciencemode2_emulator.h"
#include "server/bench/emulator/sciencemode4_emulator.h"
#include "server/bench/sciencemode4_packet.h"
#include "server/bench/sciencemode4_stimulator.h"
#include "server/bench/simulated_bench.h"
#include "server/bench/virtual_subject.h"
#include "server/bench/sciencemode2_packet.h"
#include "server/bench/sciencemode2_stimulator.h"
#include "server/bench/serial_port.h"

namespace {

using namespace fesbench::server;
using namespace fesbench::server::sciencemode2;

// Arg 2: a ScienceMode2 StartChannelListMode on a port with the RehaStim 2's
// settings; Arg 4: a ScienceMode4 biphasic Ll_Channel_Config on a port with
// the P24's. Counters p50_us / p99_us: the distribution of the iterations.
void BM_CommandToWire(benchmark::State& state) {
  const bool p24 = state.range(0) == 4;
  const int master = ::posix_openpt(O_RDWR | O_NOCTTY);
  if (master < 0 || ::grantpt(master) != 0 || ::unlockpt(master) != 0) {
    state.SkipWithError("no pty");
    return;
  }
  termios tio{};
  ::tcgetattr(master, &tio);
  ::cfmakeraw(&tio);
  ::tcsetattr(master, TCSANOW, &tio);
  SerialPort port;
  if (!port.Open(::ptsname(master), p24 ? ScienceMode4Settings() : ScienceMode2Settings()).ok()) {
    state.SkipWithError("cannot open the pty slave");
    return;
  }
  std::uint8_t number = 0;
  std::uint8_t buffer[256];
  int ma = 0;
  std::vector<double> us;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<std::uint8_t> wire;
    if (p24) {
      const sciencemode4::Point points[] = {{300, ma * 0.5}, {100, 0.0}, {300, -ma * 0.5}};
      wire = *sciencemode4::BuildLlChannelConfig(number++ & 0x3F, 1, 0, points);
    } else {
      const ChannelPulse pulse{0, 300, ma};
      wire = *BuildStartChannelListMode(number++, std::span(&pulse, 1));
    }
    ma = (ma + 1) % 100;
    if (!port.Write(wire).ok()) {
      state.SkipWithError("write failed");
      break;
    }
    std::size_t got = 0;
    while (got < wire.size()) {
      pollfd p{master, POLLIN, 0};
      ::poll(&p, 1, 100);
      const ssize_t n = ::read(master, buffer, sizeof buffer);
      if (n > 0) got += static_cast<std::size_t>(n);
    }
    us.push_back(
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
  }
  ::close(master);
  if (!us.empty()) {
    std::sort(us.begin(), us.end());
    state.counters["p50_us"] = us[us.size() / 2];
    state.counters["p99_us"] = us[std::min(us.size() - 1, us.size() * 99 / 100)];
  }
}
BENCHMARK(BM_CommandToWire)->Arg(2)->Arg(4)->UseRealTime()->Unit(benchmark::kMicrosecond);

void BM_AcknowledgedUpdate(benchmark::State& state) {
  const std::unique_ptr<Emulator> emulator_owner = Emulator::Open().value();
  Emulator& emulator = *emulator_owner;
  StimulatorConfig config;
  config.port_path = emulator.port_path();
  Stimulator stim(config);
  if (!stim.Connect().ok()) {
    state.SkipWithError(stim.fault().message().c_str());
    return;
  }
  int ma = 0;
  for (auto _ : state) {
    if (!stim.SetAmplitude(ma).ok()) {
      state.SkipWithError(stim.fault().message().c_str());
      break;
    }
    ma = (ma + 1) % 100;
  }
  (void)stim.Stop();
}
BENCHMARK(BM_AcknowledgedUpdate)->UseRealTime()->Unit(benchmark::kMicrosecond);

void BM_EStopToDevice(benchmark::State& state) {
  const std::unique_ptr<Emulator> emulator_owner = Emulator::Open().value();
  Emulator& emulator = *emulator_owner;
  StimulatorConfig config;
  config.port_path = emulator.port_path();
  auto stim = std::make_unique<Stimulator>(config);
  if (!stim->Connect().ok()) {
    state.SkipWithError(stim->fault().message().c_str());
    return;
  }
  ComposedBench bench(SimulatedBench::Create(DrawVirtualSubject(1)).value(), std::move(stim));
  bench.SetStimulationCeiling(30.0);
  for (auto _ : state) {
    state.PauseTiming();
    bench.ClearHardwareEStop();
    bench.SetStimAmplitude(20.0);
    while (!emulator.stimulating()) std::this_thread::yield();
    state.ResumeTiming();
    std::thread([&] { bench.HardwareEStop(); }).join();
    while (emulator.stimulating()) std::this_thread::yield();
  }
}
BENCHMARK(BM_EStopToDevice)->UseRealTime()->Unit(benchmark::kMicrosecond);

void BM_Sm4PulseAcknowledged(benchmark::State& state) {
  const std::unique_ptr<sciencemode4::Emulator> emulator_owner =
      sciencemode4::Emulator::Open().value();
  sciencemode4::Emulator& emulator = *emulator_owner;
  sciencemode4::StimulatorConfig config;
  config.port_path = emulator.port_path();
  sciencemode4::Stimulator stim(config);
  if (!stim.Connect().ok()) {
    state.SkipWithError(stim.fault().message().c_str());
    return;
  }
  double ma = 1.0;
  for (auto _ : state) {
    if (!stim.SinglePulse(ma).ok()) {
      state.SkipWithError(stim.fault().message().c_str());
      break;
    }
    ma = ma >= 60.0 ? 1.0 : ma + 0.5;
  }
}
BENCHMARK(BM_Sm4PulseAcknowledged)->UseRealTime()->Unit(benchmark::kMicrosecond);

}  // namespace
