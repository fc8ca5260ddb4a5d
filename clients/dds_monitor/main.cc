// fesbench-dds-monitor: a DDS client of fesbench-server (docs/API.md, "DDS").
//   fesbench-dds-monitor [--domain N] [--transport T] [--profile F]
//                        [--security DIR [--identity NAME]] [--timeout S] <command>
//   benches                          live benches and their state
//   samples --run ID [--csv FILE] [--max N]   print (or record) a run's samples until it ends
//   params --subject ID --leg ID     the latest parameter set of a subject's leg
//   estop --token T [--bench ID]     e-stop (any signed-in user)
// Exit codes: 0 ok, 1 refused / not found / data lost, 2 usage, 3 no server found.

#include <CLI/CLI.hpp>
#include <fstream>
#include <iostream>

#include "clients/dds_monitor/monitor.h"

namespace {

int ExitCode(const fesbench::api::Status& status) {
  if (status.ok()) return 0;
  std::cerr << "fesbench-dds-monitor: " << status.ToString() << std::endl;
  return status.code() == fesbench::api::ErrorCode::kUnavailable ? 3 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace fesbench;
  CLI::App app{"fesbench-dds-monitor: watch and e-stop fesbench benches over DDS"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("fesbench-dds-monitor ") + FESBENCH_VERSION);
  int domain = 0;
  std::string transport = "auto";
  std::string profile;
  double timeout_s = 5.0;
  app.add_option("--domain", domain, "DDS domain id (default 0)")->check(CLI::Range(0, 232));
  app.add_option("--transport", transport, "auto, shm, udp, udp-loopback (default auto)")
      ->check(CLI::IsMember({"auto", "shm", "udp", "udp-loopback"}));
  app.add_option("--profile", profile, "Fast DDS XML profile file")->check(CLI::ExistingFile);
  std::string security_dir, identity = "operator";
  app.add_option("--security", security_dir,
                 "secured DDS: a lab PKI directory made by scripts/make-dds-pki.sh")
      ->check(CLI::ExistingDirectory);
  app.add_option("--identity", identity,
                 "this monitor's identity in --security (default operator)");
  app.add_option("--timeout", timeout_s, "seconds to wait for a server (default 5)")
      ->check(CLI::Range(0.1, 3600.0));

  auto* benches = app.add_subcommand("benches", "list live benches and their state");
  auto* samples = app.add_subcommand("samples", "print or record the samples of a run");
  std::int64_t run_id = 0;
  std::string csv_path;
  std::uint64_t max_samples = 0;
  samples->add_option("--run", run_id, "run id")->required();
  samples->add_option("--csv", csv_path, "write CSV to this file instead of printing");
  samples->add_option("--max", max_samples, "stop after this many samples (0: at the run's end)");
  auto* params = app.add_subcommand("params", "show the latest parameter set of a leg");
  std::int64_t subject_id = 0, leg_id = 0;
  params->add_option("--subject", subject_id, "subject id")->required();
  params->add_option("--leg", leg_id, "leg id")->required();
  auto* estop = app.add_subcommand("estop", "emergency stop (any signed-in user)");
  std::string token, bench_id;
  estop->add_option("--token", token, "bearer token (or env FESBENCH_TOKEN)")
      ->envname("FESBENCH_TOKEN")
      ->required();
  estop->add_option("--bench", bench_id, "bench id (default: every bench on the domain)");
  CLI11_PARSE(app, argc, argv);

  dds_monitor::MonitorOptions options;
  options.participant.domain_id = domain;
  options.participant.transport = *fesbench::dds::ParseTransport(transport);
  options.participant.profile_file = profile;
  if (!security_dir.empty()) {
    auto files = fesbench::dds::SecurityFilesIn(security_dir, identity);
    if (!files.ok()) {
      std::cerr << "fesbench-dds-monitor: " << files.status().ToString() << std::endl;
      return 2;
    }
    options.participant.security = *files;
  }
  options.timeout_s = timeout_s;

  if (benches->parsed()) {
    auto n = dds_monitor::ListBenches(options, std::cout);
    return ExitCode(n.ok() ? api::Status::Ok() : n.status());
  }
  if (samples->parsed()) {
    std::ofstream file;
    if (!csv_path.empty()) {
      file.open(csv_path);
      if (!file) {
        std::cerr << "fesbench-dds-monitor: cannot write " << csv_path << std::endl;
        return 1;
      }
    }
    std::ostream& out = csv_path.empty() ? std::cout : file;
    auto n = dds_monitor::StreamSamples(options, run_id, !csv_path.empty(), max_samples, out);
    if (n.ok() && !csv_path.empty()) {
      std::cerr << "fesbench-dds-monitor: " << *n << " samples of run " << run_id << " written to "
                << csv_path << std::endl;
    }
    return ExitCode(n.ok() ? api::Status::Ok() : n.status());
  }
  if (params->parsed()) {
    return ExitCode(dds_monitor::ShowParameterSet(options, subject_id, leg_id, std::cout));
  }
  return ExitCode(dds_monitor::SendEStop(options, token, bench_id, std::cout));
}
