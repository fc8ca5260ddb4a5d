// fesbench-sm2-emulator: a RehaStim2 (ScienceMode2) or, with --device sm4, a
// P24 (ScienceMode4 low level) emulator on a pseudo-terminal, for dry runs
// and tests without hardware. Prints the port path on stdout, then records
// every delivery as JSON lines.

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <thread>

#include "server/bench/emulator/sciencemode2_emulator.h"
#include "server/bench/emulator/sciencemode4_emulator.h"

namespace {
std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop = true; }

void Wait(const std::string& port_path) {
  std::cout << port_path << std::endl;
  while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(50));
}

// The exit code: 1 if no pseudo-terminal opens.
int RunSm2(const std::string& fault, const std::string& log_path) {
  using fesbench::server::sciencemode2::Emulator;
  using fesbench::server::sciencemode2::EmulatorFault;
  auto opened = Emulator::Open();
  if (!opened.ok()) {
    std::cerr << opened.status().message() << "\n";
    return 1;
  }
  Emulator& emulator = **opened;
  if (fault == "corrupt-replies") emulator.set_fault(EmulatorFault::kCorruptReplies);
  if (fault == "silent") emulator.set_fault(EmulatorFault::kSilent);
  if (fault == "wrong-mode") emulator.set_fault(EmulatorFault::kWrongMode);
  Wait(emulator.port_path());
  if (log_path.empty()) return 0;
  std::ofstream out(log_path);
  for (const auto& d : emulator.deliveries()) {
    out << "{\"t_s\":" << d.t_s << ",\"channel\":" << d.channel << ",\"current_ma\":" << d.current_ma
        << ",\"pulse_width_us\":" << d.pulse_width_us << ",\"stop\":" << (d.stop ? "true" : "false")
        << ",\"reason\":\"" << d.reason << "\"}\n";
  }
  return 0;
}

// The exit code: 1 if no pseudo-terminal opens.
int RunSm4(const std::string& fault, const std::string& log_path) {
  using fesbench::server::sciencemode4::Emulator;
  using fesbench::server::sciencemode4::EmulatorFault;
  auto opened = Emulator::Open();
  if (!opened.ok()) {
    std::cerr << opened.status().message() << "\n";
    return 1;
  }
  Emulator& emulator = **opened;
  if (fault == "corrupt-replies") emulator.set_fault(EmulatorFault::kCorruptReplies);
  if (fault == "silent") emulator.set_fault(EmulatorFault::kSilent);
  if (fault == "wrong-mode") emulator.set_fault(EmulatorFault::kWrongMode);
  Wait(emulator.port_path());
  if (log_path.empty()) return 0;
  std::ofstream out(log_path);
  for (const auto& d : emulator.deliveries()) {
    const int width = d.points.empty() ? 0 : d.points.front().time_us;
    out << "{\"t_s\":" << d.t_s << ",\"channel\":" << d.channel
        << ",\"current_ma\":" << d.current_ma() << ",\"pulse_width_us\":" << width
        << ",\"stop\":" << (d.stop ? "true" : "false") << "}\n";
  }
  return 0;
}
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"RehaStim2 (ScienceMode2) or P24 (ScienceMode4) emulator on a pseudo-terminal"};
  app.set_version_flag("--version", std::string("fesbench-sm2-emulator ") + FESBENCH_VERSION);
  std::string log_path;
  std::string fault = "none";
  std::string device = "sm2";
  app.add_option("--device", device, "sm2 (RehaStim2, ScienceMode2) or sm4 (P24, low level)")
      ->check(CLI::IsMember({"sm2", "sm4"}));
  app.add_option("--log", log_path, "write deliveries as JSON lines to this file at exit");
  app.add_option("--fault", fault,
                 "none, corrupt-replies, silent, or wrong-mode (stops on its own and says so "
                 "when asked)")
      ->check(CLI::IsMember({"none", "corrupt-replies", "silent", "wrong-mode"}));
  CLI11_PARSE(app, argc, argv);

  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  return device == "sm4" ? RunSm4(fault, log_path) : RunSm2(fault, log_path);
}
