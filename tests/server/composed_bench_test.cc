// A bench made of parts (README, "A real stimulator"): the RehaStim2 emulator behind a real
// pseudo-terminal as the stimulator, the simulated leg as sensors and motor,
// the protocol runner and the safety layer above, as the server composes
// them for --stimulator sciencemode2. What the device was asked to deliver
// ("ScienceMode2 – Description and Protocol" v1.24, §4.3
// StartChannelListMode), as the emulator records it, is held against the
// runner's commands; e-stop and device failures are held against the run.

#include "server/bench/composed_bench.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <thread>

#include "api/trial.h"
#include "server/bench/emulator/sciencemode2_emulator.h"
#include "server/bench/sciencemode2_stimulator.h"
#include "server/bench/simulated_bench.h"
#include "server/bench/virtual_subject.h"
#include "server/protocols/plan.h"
#include "server/protocols/runner.h"

namespace fesbench::server {
namespace {

using namespace std::chrono_literals;
using protocols::ProtocolRunner;
using protocols::RunResult;
using protocols::RunState;
using protocols::SubjectContext;
using sciencemode2::Emulator;
using sciencemode2::EmulatorFault;

// The driver, recording every amplitude update and what the device
// accepted; `after_update` lets a test break the device mid-run.
class RecordingDevice final : public StimulatorDevice {
 public:
  explicit RecordingDevice(std::unique_ptr<sciencemode2::Stimulator> device)
      : device_(std::move(device)) {}
  struct Update {
    double commanded_ma;
    double accepted_ma;
    bool ok;
  };
  std::string_view name() const override { return device_->name(); }
  double max_current_ma() const override { return device_->max_current_ma(); }
  double current_step_ma() const override { return device_->current_step_ma(); }
  void SetSessionLimit(double max_ma) override { device_->SetSessionLimit(max_ma); }
  api::Status SetAmplitude(double stim_ma) override {
    api::Status status = device_->SetAmplitude(stim_ma);
    updates.push_back({stim_ma, device_->delivered_ma(), status.ok()});
    if (after_update) after_update(updates.size());
    return status;
  }
  api::Result<double> SinglePulse(double stim_ma) override {
    api::Result<double> delivered = device_->SinglePulse(stim_ma);
    singles.push_back({stim_ma, delivered.ok() ? *delivered : -1.0, delivered.ok()});
    return delivered;
  }
  double delivered_ma() const override { return device_->delivered_ma(); }
  std::chrono::steady_clock::time_point last_command_written() const override {
    return device_->last_command_written();
  }
  std::optional<double> own_pulse_rate_hz() const override { return device_->own_pulse_rate_hz(); }
  api::Status Service() override { return device_->Service(); }
  void EmergencyStop() override { device_->EmergencyStop(); }
  void ClearEStop() override { device_->ClearEStop(); }
  bool estopped() const override { return device_->estopped(); }
  api::Status fault() const override { return device_->fault(); }

  std::vector<Update> updates;
  std::vector<Update> singles;
  std::function<void(std::size_t)> after_update;

 private:
  std::unique_ptr<sciencemode2::Stimulator> device_;
};

struct Rig {
  explicit Rig(std::uint64_t seed) : subject(DrawVirtualSubject(seed)) {
    sciencemode2::StimulatorConfig config;
    config.port_path = emulator.port_path();
    config.channel = 1;
    config.reply_timeout = 150ms;
    auto sm2 = std::make_unique<sciencemode2::Stimulator>(config);
    const api::Status connect = sm2->Connect();
    connected = connect.ok();
    connect_fault = connect.ToString();
    auto recording = std::make_unique<RecordingDevice>(std::move(sm2));
    device = recording.get();
    SimulatedBenchOptions options;  // time scale 0: as fast as the device answers
    // As the server opens it: the leg's pulse clock at the device's own rate.
    options.limits.pulse_rate_hz = sciencemode2::DevicePulseRateHz(options.limits.pulse_rate_hz);
    bench = std::make_unique<ComposedBench>(SimulatedBench::Create(subject, options).value(),
                                            std::move(recording));
    safe = std::make_unique<SafeBench>(*bench, log.sink());
  }
  SubjectContext Context() const {
    SubjectContext s;
    s.threshold_ma = subject.threshold_ma;
    s.max_tolerated_ma = subject.max_tolerated_ma;
    s.min_angle_deg = 15.0;
    s.max_angle_deg = 108.0;
    s.inertia_kgm2 = subject.truth.passive.inertia_kgm2;
    return s;
  }
  RunResult Run(const std::string& protocol, const protocols::ParameterValues& values = {}) {
    const SubjectContext ctx = Context();
    auto plan = protocols::MakePlan(protocol, values, ctx);
    EXPECT_TRUE(plan.ok()) << plan.status().ToString();
    protocols::RunnerOptions options;
    options.arm_watchdog = false;
    ProtocolRunner runner(*safe, &log, nullptr, options);
    return runner.Run(*plan, ctx);
  }

  // A test's rig: a pseudo-terminal that will not open is the machine's
  // fault, not the code's (Emulator::Open).
  std::unique_ptr<Emulator> emulator_owner = Emulator::Open().value();
  Emulator& emulator = *emulator_owner;
  VirtualSubject subject;
  bool connected = false;
  std::string connect_fault;
  RecordingDevice* device = nullptr;
  std::unique_ptr<ComposedBench> bench;
  protocols::SafetyEventLog log;
  std::unique_ptr<SafeBench> safe;
};

TEST(ComposedBench, NamesItsPartsAndTakesTheDeviceLimit) {
  Rig rig(7);
  ASSERT_TRUE(rig.connected) << rig.connect_fault;
  EXPECT_EQ(rig.bench->kind(), "sciencemode2+sim");
  EXPECT_EQ(rig.bench->limits().max_stim_ma, 100.0);  // min(bench 100, device 130)
}

TEST(ComposedBench, RampRunDeliversTheRunnersCommandsWithinTheDeviceResolution) {
  Rig rig(7);
  ASSERT_TRUE(rig.connected) << rig.connect_fault;
  const RunResult r = rig.Run("isometric_ramp_irc");
  ASSERT_EQ(r.state, RunState::kDone) << r.reason;

  // What the device was asked for, in order, is what the driver sent: the
  // emulator's StartChannelListMode records against the driver's updates.
  const auto& updates = rig.device->updates;
  std::vector<sciencemode2::Delivery> starts, singles;
  for (const auto& d : rig.emulator.deliveries()) {
    if (d.reason == "single") {
      singles.push_back(d);
    } else if (!d.stop) {
      starts.push_back(d);
    }
  }
  // The two impulses at max (§5.3.3) are the device's single pulses.
  ASSERT_EQ(rig.device->singles.size(), 2u);
  ASSERT_EQ(singles.size(), 2u);
  for (std::size_t i = 0; i < singles.size(); ++i) {
    EXPECT_EQ(singles[i].current_ma, rig.device->singles[i].accepted_ma);
    EXPECT_LE(singles[i].current_ma, rig.device->singles[i].commanded_ma + 1e-9);
    EXPECT_GT(singles[i].current_ma, rig.device->singles[i].commanded_ma - 1.0);
  }
  ASSERT_GT(updates.size(), 20u);
  ASSERT_EQ(starts.size(), updates.size());
  const double ceiling = rig.subject.max_tolerated_ma;
  for (std::size_t i = 0; i < updates.size(); ++i) {
    SCOPED_TRACE(i);
    ASSERT_TRUE(updates[i].ok);
    EXPECT_EQ(starts[i].channel, 1);
    EXPECT_EQ(starts[i].pulse_width_us, 300);
    EXPECT_EQ(starts[i].current_ma, updates[i].accepted_ma);
    // Rounded down to the 1 mA step: never above the command or the ceiling.
    EXPECT_LE(updates[i].accepted_ma, updates[i].commanded_ma + 1e-9);
    EXPECT_GT(updates[i].accepted_ma, updates[i].commanded_ma - 1.0);
    EXPECT_LE(starts[i].current_ma, ceiling);
  }
  // The ramps reach the top of the planned ramp: within one step of it.
  double peak_command = 0.0;
  for (const auto& u : updates) peak_command = std::max(peak_command, u.commanded_ma);
  double peak_device = 0.0;
  for (const auto& d : starts) peak_device = std::max<double>(peak_device, d.current_ma);
  EXPECT_GT(peak_device, peak_command - 1.0);

  // The leg got exactly what the device accepted: every pulse it received
  // (the trial's read-back) is within one step below the runner's command
  // at the pulse's time (the 200 Hz command record, ±1 sample).
  std::size_t pulses = 0;
  for (const auto& rec : r.trials) {
    const api::Trial& t = rec.trial;
    ASSERT_TRUE(t.pulses.has_value());
    const std::vector<double>& command = *t.Values("stim_ma");
    const double dt = 1.0 / 200.0;
    for (std::size_t i = 0; i < t.pulses->size(); ++i) {
      const double at = t.pulses->t_s[i], ma = t.pulses->stim_ma[i];
      ++pulses;
      const auto k = static_cast<std::ptrdiff_t>(std::floor(at / dt + 1e-9));
      double lo = 1e9, hi = -1e9;
      for (std::ptrdiff_t j = std::max<std::ptrdiff_t>(k - 1, 0);
           j <= std::min<std::ptrdiff_t>(k + 1, static_cast<std::ptrdiff_t>(command.size()) - 1);
           ++j) {
        lo = std::min(lo, command[static_cast<std::size_t>(j)]);
        hi = std::max(hi, command[static_cast<std::size_t>(j)]);
      }
      EXPECT_DOUBLE_EQ(ma, std::floor(ma)) << t.name.value_or("") << " t=" << at;
      EXPECT_LE(ma, hi + 1e-9) << t.name.value_or("") << " t=" << at;
      EXPECT_GT(ma, lo - 1.0 - 1e-9) << t.name.value_or("") << " t=" << at;
    }
  }
  EXPECT_GT(pulses, 100u);
  EXPECT_FALSE(rig.bench->HardwareEStopped());
}

TEST(ComposedBench, EStopFromAnotherThreadReachesTheDeviceWithinOnePulsePeriod) {
  Rig rig(7);
  ASSERT_TRUE(rig.connected) << rig.connect_fault;
  rig.safe->Configure({.max_stim_ma = 30.0});
  rig.safe->SetStimAmplitude(20.0);
  rig.safe->AdvanceTo(0.1);
  ASSERT_TRUE(rig.emulator.stimulating());
  const auto t0 = std::chrono::steady_clock::now();
  std::thread([&] { rig.safe->EStop("test e-stop button"); }).join();
  while (rig.emulator.stimulating() && std::chrono::steady_clock::now() - t0 < 1s) {
    std::this_thread::sleep_for(50us);
  }
  const auto latency = std::chrono::steady_clock::now() - t0;
  EXPECT_FALSE(rig.emulator.stimulating());
  // The device's control period is its pulse period (33 Hz: 30.3 ms).
  const double latency_ms = std::chrono::duration<double, std::milli>(latency).count();
  RecordProperty("estop_to_device_ms", std::to_string(latency_ms));
  EXPECT_LT(latency, 30ms) << latency_ms << " ms";
  EXPECT_TRUE(rig.emulator.deliveries().back().stop);
  // Latched: nothing stimulating reaches the device until cleared.
  const std::size_t sent = rig.emulator.deliveries().size();
  rig.safe->SetStimAmplitude(25.0);
  rig.safe->AdvanceTo(0.2);
  EXPECT_EQ(rig.emulator.deliveries().size(), sent);
  rig.safe->ClearEStop("test");
  rig.safe->SetStimAmplitude(12.0);
  rig.safe->AdvanceTo(0.3);
  EXPECT_TRUE(rig.emulator.stimulating());
  EXPECT_EQ(rig.emulator.deliveries().back().current_ma, 12);
}

TEST(ComposedBench, ADriverRefusesAboveTheSessionCeilingOnItsOwn) {
  // A faulty caller below SafeBench commands 40 mA on a 30 mA session: the
  // driver's own check (the session ceiling SafeBench passed down) refuses
  // it without sending, and the bench latches with the driver's reason.
  Rig rig(7);
  ASSERT_TRUE(rig.connected) << rig.connect_fault;
  rig.safe->Configure({.max_stim_ma = 30.0});
  rig.bench->SetStimAmplitude(40.0);
  EXPECT_TRUE(rig.bench->HardwareEStopped());
  const api::Status fault = rig.bench->HardwareFault();
  EXPECT_EQ(fault.code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_NE(fault.message().find("refused 40"), std::string::npos) << fault.ToString();
  for (const auto& d : rig.emulator.deliveries()) EXPECT_LE(d.current_ma, 30);
}

TEST(ComposedBench, ImpulseProtocolIsThirtySinglePulsesOfTheRunnersAmplitudes) {
  // §5.3.2: 30 single pulses from below threshold to max, 1 s apart.
  Rig rig(7);
  ASSERT_TRUE(rig.connected) << rig.connect_fault;
  const RunResult r = rig.Run("isometric_impulse_irc");
  ASSERT_EQ(r.state, RunState::kDone) << r.reason;
  std::vector<sciencemode2::Delivery> singles;
  for (const auto& d : rig.emulator.deliveries()) {
    if (d.reason == "single") singles.push_back(d);
  }
  ASSERT_EQ(singles.size(), 30u);
  ASSERT_EQ(r.trials.size(), 1u);
  const api::PulseRecord& read_back = *r.trials[0].trial.pulses;
  std::vector<double> leg;  // what reached the virtual leg, > 0
  for (double ma : read_back.stim_ma) {
    if (ma > 0.0) leg.push_back(ma);
  }
  ASSERT_EQ(leg.size(), 30u);
  for (std::size_t i = 0; i < 30; ++i) {
    SCOPED_TRACE(i);
    const auto& u = rig.device->singles[i];
    EXPECT_EQ(singles[i].current_ma, u.accepted_ma);
    EXPECT_EQ(leg[i], u.accepted_ma);
    EXPECT_LE(u.accepted_ma, u.commanded_ma + 1e-9);
    EXPECT_GT(u.accepted_ma, u.commanded_ma - 1.0);
  }
  EXPECT_LT(rig.device->singles.front().commanded_ma, rig.device->singles.back().commanded_ma);
}

TEST(ComposedBench, RapidRoutineRunsThroughTheDevice) {
  Rig rig(7);
  ASSERT_TRUE(rig.connected) << rig.connect_fault;
  const RunResult r = rig.Run("rapid_parameterisation");
  ASSERT_EQ(r.state, RunState::kDone) << r.reason;
  for (const auto& d : rig.emulator.deliveries()) {
    EXPECT_LE(d.current_ma, rig.subject.max_tolerated_ma);
  }
  EXPECT_GT(rig.device->updates.size(), 50u);
  EXPECT_FALSE(rig.bench->HardwareEStopped());
}

// A device that fails in the middle of a run: the run ends at once with the
// device's reason, stimulation is stopped, and the reason is a safety event.
struct Failure {
  const char* name;
  std::function<void(Emulator&)> inject;
  const char* reason;
};

void PrintTo(const Failure& f, std::ostream* os) { *os << f.name; }

// The trials record what the device was told and when: each command of the
// log is one the emulator read, with the same current, within one device
// tick (its pulse period) after the time the log gives; commanded is the request
// rounded down to the 1 mA step; the pulses are on the device's grid
// (30.5 ms, §4.3: 32.787 Hz for 33 Hz asked).
TEST(ComposedBench, TrialsRecordWhatTheDeviceWasToldAndWhen) {
  Rig rig(5);
  ASSERT_TRUE(rig.connected) << rig.connect_fault;
  const RunResult r = rig.Run("isometric_ramp_irc");
  ASSERT_EQ(r.state, RunState::kDone) << r.reason;
  const auto deliveries = rig.emulator.deliveries();
  const double device_hz = 1000.0 / 30.5;
  std::size_t matched = 0, singles = 0;
  double worst_ms = 0.0;
  for (const auto& rec : r.trials) {
    const api::Trial& t = rec.trial;
    ASSERT_TRUE(t.device_commands) << t.name.value_or("");
    ASSERT_TRUE(t.start_time_unix_ms);
    const api::DeviceCommandLog& log = *t.device_commands;
    EXPECT_EQ(log.device, "sciencemode2");
    EXPECT_NEAR(log.pulse_rate_hz, device_hz, 1e-9);
    EXPECT_EQ(log.current_step_ma, 1.0);
    ASSERT_TRUE(t.pulses);
    EXPECT_NEAR(t.pulses->pulse_rate_hz, device_hz, 1e-9);
    EXPECT_TRUE(api::ValidateTrial(t).ok());
    for (std::size_t k = 0; k < log.size(); ++k) {
      EXPECT_EQ(log.commanded_ma[k], std::floor(log.requested_ma[k] + 1e-9)) << k;
      const auto at = log.start_monotonic_ns + static_cast<std::int64_t>(log.t_s[k] * 1e9);
      const sciencemode2::Delivery* seen = nullptr;
      for (const auto& d : deliveries) {
        if (!d.stop && d.current_ma == log.commanded_ma[k] &&
            (d.reason == "single") == static_cast<bool>(log.single_pulse[k]) &&
            d.steady_ns >= at - 1000 &&
            d.steady_ns - at <= static_cast<std::int64_t>(1e9 / log.pulse_rate_hz)) {
          seen = &d;
          break;
        }
      }
      if (seen == nullptr) {
        for (const auto& d : deliveries) {
          if (std::abs(d.steady_ns - at) < 50'000'000) {
            std::printf("  delivery %+.3f ms: %d mA %s%s\n", (d.steady_ns - at) / 1e6, d.current_ma,
                        d.reason.c_str(), d.stop ? " stop" : "");
          }
        }
      }
      ASSERT_NE(seen, nullptr) << "command " << k << " of " << t.name.value_or("") << " at "
                               << log.t_s[k] << " s, " << log.commanded_ma[k] << " mA, single "
                               << log.single_pulse[k];
      worst_ms = std::max(worst_ms, (seen->steady_ns - at) / 1e6);
      ++matched;
      if (log.single_pulse[k]) ++singles;
    }
  }
  std::printf("[ figure ] %zu device commands logged (%zu single pulses), the emulator read each "
              "at most %.3f ms after its logged time\n",
              matched, singles, worst_ms);
  EXPECT_GT(matched, 20u);
  EXPECT_EQ(singles, 2u);  // the ramp protocol's two impulses
}

class DeviceFailure : public ::testing::TestWithParam<Failure> {};

TEST_P(DeviceFailure, EndsTheRunWithTheDevicesReason) {
  Rig rig(7);
  ASSERT_TRUE(rig.connected) << rig.connect_fault;
  rig.device->after_update = [&](std::size_t n) {
    if (n == 5) GetParam().inject(rig.emulator);  // within the first ramp
  };
  const RunResult r = rig.Run("isometric_ramp_irc");
  EXPECT_EQ(r.state, RunState::kAborted);
  // The reason names the device and what it did.
  EXPECT_NE(r.reason.find(std::string("e-stop: sciencemode2 ") + GetParam().reason),
            std::string::npos)
      << r.reason;
  EXPECT_LE(rig.device->updates.size(), 7u);  // stopped at the next update or service
  // The driver's StopChannelListMode reaches the device (which still reads
  // commands when its replies are corrupt or missing).
  const auto t0 = std::chrono::steady_clock::now();
  while (rig.emulator.stimulating() && std::chrono::steady_clock::now() - t0 < 500ms) {
    std::this_thread::sleep_for(1ms);
  }
  EXPECT_FALSE(rig.emulator.stimulating());
  bool event = false;
  for (const auto& e : rig.log.Since(0)) {
    event = event || (e.kind == SafetyEvent::Kind::kEStop &&
                      e.detail.find(GetParam().reason) != std::string::npos);
  }
  EXPECT_TRUE(event);
  // A device fault is not cleared by a person's e-stop clear: reconnect.
  rig.safe->ClearEStop("test");
  rig.safe->AdvanceTo(rig.bench->Now_s() + 0.01);
  EXPECT_TRUE(rig.safe->estopped());
}

INSTANTIATE_TEST_SUITE_P(
    Sm2, DeviceFailure,
    ::testing::Values(
        Failure{"pulled_cable", [](Emulator& e) { e.Unplug(); }, "stimulator lost"},
        Failure{"checksum_error",
                [](Emulator& e) { e.set_fault(EmulatorFault::kCorruptReplies); },
                "stimulator reply garbled: checksum error"},
        Failure{"timeout", [](Emulator& e) { e.set_fault(EmulatorFault::kSilent); },
                "stimulator timeout"}),
    [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace fesbench::server
