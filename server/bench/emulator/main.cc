// fesbench-sm2-emulator: a RehaStim2 (ScienceMode2) emulator on a
// pseudo-terminal, for dry runs and tests without hardware. Prints the port
// path on stdout, then records every delivery as JSON lines.

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <thread>

#include "server/bench/emulator/sciencemode2_emulator.h"

namespace {
std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop = true; }
}  // namespace

int main(int argc, char** argv) {
  using fesbench::server::sciencemode2::Emulator;
  using fesbench::server::sciencemode2::EmulatorFault;
  CLI::App app{"RehaStim2 (ScienceMode2) emulator on a pseudo-terminal"};
  app.set_version_flag("--version", std::string("fesbench-sm2-emulator ") + FESBENCH_VERSION);
  std::string log_path;
  std::string fault = "none";
  app.add_option("--log", log_path, "write deliveries as JSON lines to this file at exit");
  app.add_option("--fault", fault, "none, corrupt-replies or silent")
      ->check(CLI::IsMember({"none", "corrupt-replies", "silent"}));
  CLI11_PARSE(app, argc, argv);

  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  Emulator emulator;
  if (fault == "corrupt-replies") emulator.set_fault(EmulatorFault::kCorruptReplies);
  if (fault == "silent") emulator.set_fault(EmulatorFault::kSilent);
  std::cout << emulator.port_path() << std::endl;
  while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(50));

  if (!log_path.empty()) {
    std::ofstream out(log_path);
    for (const auto& d : emulator.deliveries()) {
      out << "{\"t_s\":" << d.t_s << ",\"channel\":" << d.channel
          << ",\"current_ma\":" << d.current_ma << ",\"pulse_width_us\":" << d.pulse_width_us
          << ",\"stop\":" << (d.stop ? "true" : "false") << ",\"reason\":\"" << d.reason << "\"}\n";
    }
  }
  return 0;
}
