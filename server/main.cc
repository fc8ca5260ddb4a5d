// fesbench-server: wiring only (docs/ARCHITECTURE.md). Reads flags and the optional JSON
// config (server/config.h), opens the database, bootstraps the first admin,
// builds the bench (simulated or replay) and the services, and serves the
// HTTP API until SIGTERM/SIGINT; then stops the server, shuts the services
// down (a running protocol is stopped with stimulation zero), closes the
// database and exits 0. Under systemd (Type=notify, README "Install on a lab
// PC") it says READY=1 once it listens and STOPPING=1 when it stops;
// without NOTIFY_SOCKET those calls do nothing. --backup and --migrate run
// one maintenance step on the database instead (server/database_maintenance.h).

#include <fcntl.h>
#include <pthread.h>
#include <sys/stat.h>
#include <systemd/sd-daemon.h>
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <thread>

#include "server/bench/composed_bench.h"
#include "server/bench/replay_bench.h"
#include "server/bench/sciencemode2_stimulator.h"
#include "server/bench/sciencemode4_stimulator.h"
#include "server/bench/virtual_subject.h"
#include "server/config.h"
#include "server/database_maintenance.h"
#include "server/dds/dds_server.h"
#include "server/services/bench_lock_guard.h"
#include "server/services/bench_service.h"
#include "server/services/commands.h"
#include "server/services/comparison_service.h"
#include "server/services/identification_service.h"
#include "server/services/job_pool.h"
#include "server/services/prediction_service.h"
#include "server/services/run_service.h"
#include "server/services/sample_hub.h"
#include "storage/database.h"
#include "storage/postgres_connection.h"
#include "storage/private_files.h"
#include "storage/users.h"
#include "server/http/api_routes.h"
#include "server/http/http_server.h"

namespace {

std::string HostName() {
  char name[256] = {};
  if (::gethostname(name, sizeof(name) - 1) != 0 || name[0] == '\0') return "fesbench";
  return name;
}

using namespace fesbench;

// Writes `text` to `path` readable by the owner only (0600).
api::Status WriteSecretFile(const std::filesystem::path& path, const std::string& text) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) return api::Status::Unavailable("cannot write " + path.string());
  ::fchmod(fd, 0600);
  const bool ok = ::write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size());
  ::close(fd);
  return ok ? api::Status::Ok() : api::Status::Unavailable("cannot write " + path.string());
}

// Whether standard output is the systemd journal's stream (JOURNAL_STREAM
// holds its device and inode, systemd.exec(5)): the journal keeps what is
// printed, and others than the server's user may read it (group adm).
bool OutputGoesToTheJournal() {
  const char* stream = std::getenv("JOURNAL_STREAM");
  struct stat info {};
  if (stream == nullptr || ::fstat(STDOUT_FILENO, &info) != 0) return false;
  return std::string(stream) == std::to_string(info.st_dev) + ":" + std::to_string(info.st_ino);
}

// At first start on an empty database: an admin user and its token, written
// to admin.token (0600) beside the database file and printed once, unless
// the output goes to the journal (the service): then only the file is named.
api::Status BootstrapAdmin(storage::Database& db, const std::filesystem::path& token_path) {
  storage::UserRepository users(db);
  auto existing = users.ListUsers();
  if (!existing.ok()) return existing.status();
  if (!existing->empty()) return api::Status::Ok();
  auto admin = users.CreateUser("admin", storage::Role::kAdmin);
  if (!admin.ok()) return admin.status();
  auto token = users.IssueToken(admin->id, "bootstrap admin token");
  if (!token.ok()) return token.status();
  if (auto st = WriteSecretFile(token_path, token->token + "\n"); !st.ok()) return st;
  if (OutputGoesToTheJournal()) {
    std::cout << "fesbench-server: created user admin; its token is in " << token_path.string()
              << " (not printed: this output goes to the journal)\n";
  } else {
    std::cout << "fesbench-server: created user admin; its token (shown once): " << token->token
              << "\n";
  }
  return api::Status::Ok();
}

// The bench: a simulated leg (seeded virtual subject) or a replay of CSV
// trials. `simulated` is the simulated one (its subject can be swapped), or null.
struct OpenedBench {
  std::unique_ptr<server::Bench> bench;
  server::SwappableSimulatedBench* simulated = nullptr;
};
api::Result<OpenedBench> OpenBench(const server::ServerConfig& config) {
  OpenedBench opened;
  if (config.bench == "sim") {
    server::SimulatedBenchOptions options;
    options.time_scale = config.time_scale;
    options.seed = config.seed;
    options.limits.max_stop_impact_deg_s = config.max_stop_impact_deg_s;
    if (config.stimulator == "sciencemode2") {
      // The RehaStim 2 fires its channel list at its own period (33 Hz asked,
      // 30.5 ms fired): the leg's pulse clock runs at that rate, so the leg
      // and the stored trials get the pulses on the device's grid.
      options.limits.pulse_rate_hz =
          server::sciencemode2::DevicePulseRateHz(options.limits.pulse_rate_hz);
    }
    auto sim =
        server::SwappableSimulatedBench::Create(server::DrawVirtualSubject(config.seed), options);
    if (!sim.ok()) return sim.status();
    opened.simulated = sim->get();
    opened.bench = std::move(*sim);
    return opened;
  }
  server::ReplayBenchOptions options;
  options.time_scale = config.time_scale;
  options.limits.max_stop_impact_deg_s = config.max_stop_impact_deg_s;
  std::vector<std::filesystem::path> files(config.replay.begin(), config.replay.end());
  auto replay = server::ReplayBench::FromCsvFiles(files, options);
  if (!replay.ok()) return replay.status();
  opened.bench = std::move(*replay);
  return opened;
}

// Connects a stimulator device and puts it in place of `bench`'s own (issue
// 21), when one is configured.
template <typename Device, typename Config>
api::Status Compose(Config device_config, std::unique_ptr<server::Bench>& bench) {
  auto device = std::make_unique<Device>(std::move(device_config));
  if (api::Status connected = device->Connect(); !connected.ok()) return connected;
  bench = std::make_unique<server::ComposedBench>(std::move(bench), std::move(device));
  return api::Status::Ok();
}

// A real stimulator in place of the bench's own (README, "A real stimulator"): the device
// delivers; the sensors and the motor stay the bench's.
api::Status AttachStimulator(const server::ServerConfig& config,
                             std::unique_ptr<server::Bench>& bench) {
  const server::BenchLimits& limits = bench->limits();
  if (config.stimulator == "sciencemode2") {
    server::sciencemode2::StimulatorConfig sm2;
    sm2.port_path = config.stimulator_port;
    sm2.channel = config.stimulator_channel;
    sm2.pulse_rate_hz = limits.pulse_rate_hz;
    sm2.pulse_width_us = static_cast<int>(limits.pulse_width_us);
    sm2.session_max_ma = limits.max_stim_ma;
    return Compose<server::sciencemode2::Stimulator>(sm2, bench);
  }
  if (config.stimulator == "sciencemode4") {
    server::sciencemode4::StimulatorConfig sm4;
    sm4.port_path = config.stimulator_port;
    sm4.channel = config.stimulator_channel;
    sm4.pulse_width_us = static_cast<int>(limits.pulse_width_us);
    sm4.session_max_ma = limits.max_stim_ma;
    return Compose<server::sciencemode4::Stimulator>(sm4, bench);
  }
  return api::Status::Ok();
}

// The DDS front end (docs/API.md, "DDS"): the same services, commands through the
// same RunService calls and audit log as HTTP.
api::Result<std::unique_ptr<server::dds::DdsServer>> StartDds(
    const server::ServerConfig& config, const std::string& bench_id, storage::Database& db,
    server::services::RunService& runs, server::services::SampleHub& hub,
    server::services::CommandService& commands) {
  server::dds::DdsServerOptions options;
  options.participant.domain_id = config.dds_domain;
  options.participant.transport = *fesbench::dds::ParseTransport(config.dds_transport);
  options.participant.profile_file = config.dds_profile;
  options.participant.profile_name = config.dds_profile_name;
  options.participant.name = "fesbench-server";
  if (!config.dds_security.empty()) {
    auto files = fesbench::dds::SecurityFilesIn(config.dds_security, config.dds_identity);
    if (!files.ok()) return files.status();
    options.participant.security = *files;
  }
  options.bench_id = config.dds_bench_id.empty() ? bench_id : config.dds_bench_id;
  return server::dds::DdsServer::Start(options, db, runs, hub, commands);
}

// Runs a crash left open end failed, and an e-stop latched before the stop
// is latched again; both said on the console.
api::Status Recover(server::services::RunService& runs) {
  auto recovered = runs.RecoverAfterRestart();
  if (!recovered.ok()) return recovered.status();
  for (const std::int64_t id : recovered->failed_run_ids) {
    std::cout << "fesbench-server: run " << id << " was left unfinished: failed ("
              << server::services::kStoppedDuringRunReason << ")\n";
  }
  if (recovered->estop_source) {
    std::cout << "fesbench-server: e-stop still latched (" << *recovered->estop_source
              << "): clear it with DELETE /api/v1/bench/estop\n";
  }
  return api::Status::Ok();
}

// What the server is and where it listens, once it is listening.
void PrintBanner(const server::ServerConfig& config, std::string_view bench_kind,
                 const std::string& db_name, const std::string& bench_id,
                 const std::filesystem::path& token_path, const server::dds::DdsServer* dds,
                 int port) {
  const std::string scheme = config.tls_cert.empty() ? "http" : "https";
  const std::string host = config.bind == "0.0.0.0" ? "127.0.0.1" : config.bind;
  const std::string dds_text =
      dds ? "domain " + std::to_string(config.dds_domain) + ", transport " +
                config.dds_transport + ", bench id " + dds->bench_id() +
                (config.dds_security.empty() ? std::string(", unsecured")
                                             : ", secured as identity " + config.dds_identity)
          : std::string("off");
  const bool web_built =
      std::filesystem::is_regular_file(std::filesystem::path(config.web_root) / "index.html");
  std::cout << "fesbench-server: bench " << bench_kind << ", time scale " << config.time_scale
            << ", database " << db_name << ", bench id " << bench_id << "\n"
            << "fesbench-server: admin token file " << token_path.string() << "\n"
            << "fesbench-server: DDS " << dds_text << "\n"
            << "fesbench-server: web client "
            << (web_built ? "from " + config.web_root
                          : "not built (no index.html in --web-root \"" + config.web_root + "\")")
            << "\n"
            << "fesbench-server: listening on " << scheme << "://" << host << ":" << port << "/"
            << std::endl;
}

// The data folder and the SQLite file's folder: missing ones are made 0700
// (docs/SAFETY.md, "Files"); existing ones are left as they are, with a note
// when other users may enter them.
api::Status MakeFolders(bool postgres, const std::string& db_name,
                        const std::filesystem::path& data_dir) {
  std::vector<std::filesystem::path> folders = {data_dir};
  if (!postgres) folders.push_back(std::filesystem::path(db_name).parent_path());
  for (const auto& folder : folders) {
    std::error_code ec;
    const bool existed = std::filesystem::exists(folder, ec);
    if (auto st = storage::CreatePrivateFolders(folder); !st.ok()) return st;
    struct stat info {};
    if (existed && ::stat(folder.c_str(), &info) == 0 && (info.st_mode & 077) != 0) {
      std::cout << "fesbench-server: note: folder " << folder.string() << " is open to other users"
                << " (mode " << storage::ModeText(info.st_mode) << "); left as it is, the"
                << " server's files in it are 0600\n";
    }
  }
  return api::Status::Ok();
}

int Fail(const std::string& what, const api::Status& status) {
  std::cerr << "fesbench-server: " << what << ": " << status.ToString() << std::endl;
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    if (std::string_view(argv[i]) == "--version") {
      std::cout << "fesbench-server " << FESBENCH_VERSION << std::endl;
      return 0;
    }
  }
  // Whatever the caller's umask: the files and folders the server makes are
  // its owner's only (docs/SAFETY.md, "Files"); where they are made the
  // modes are also explicit.
  ::umask(077);
  auto parsed = server::ParseServerConfig(argc, argv, std::cout, std::cerr);
  if (parsed.exit_code) return *parsed.exit_code;
  const server::ServerConfig& config = parsed.config;

  // SIGTERM/SIGINT go to one waiting thread (blocked everywhere else, so
  // every thread created below inherits the mask).
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  std::signal(SIGPIPE, SIG_IGN);

  // The database: an SQLite file beside this server, or a PostgreSQL
  // database that several servers (one per bench) share.
  const bool postgres = storage::IsPostgresUrl(config.db);
  const std::string db_name =
      postgres ? storage::RedactedUrl(config.db) : std::filesystem::absolute(config.db).string();
  const std::filesystem::path data_dir = std::filesystem::absolute(
      !config.data_dir.empty() ? std::filesystem::path(config.data_dir)
      : postgres               ? std::filesystem::path("data")
                               : std::filesystem::absolute(config.db).parent_path());
  if (auto st = MakeFolders(postgres, db_name, data_dir); !st.ok()) return Fail("folders", st);
  const std::string bench_id = config.bench_id.empty() ? HostName() : config.bench_id;
  const server::DatabaseLocation location{postgres ? config.db : db_name, postgres, data_dir};
  if (config.task == server::ServerTask::kBackup) {
    return server::BackupDatabase(location, config.backup_keep_days, std::cout, std::cerr);
  }
  if (config.task == server::ServerTask::kMigrate) {
    return server::MigrateDatabase(location, bench_id, std::cout, std::cerr);
  }

  storage::DatabaseOptions db_options;
  db_options.path = postgres ? config.db : db_name;
  db_options.bench_id = bench_id;
  auto db = storage::Database::Open(db_options);
  if (!db.ok()) return Fail("cannot open " + db_name, db.status());
  for (const std::string& note : (*db)->open_notes()) {
    std::cout << "fesbench-server: " << note << "\n";
  }

  const std::filesystem::path token_path = data_dir / "admin.token";
  if (auto st = BootstrapAdmin(**db, token_path); !st.ok()) return Fail("admin bootstrap", st);

  auto opened = OpenBench(config);
  if (!opened.ok()) {
    return Fail(config.bench == "sim" ? "simulated bench" : "replay bench", opened.status());
  }
  std::unique_ptr<server::Bench> bench = std::move(opened->bench);
  server::SwappableSimulatedBench* simulated = opened->simulated;
  if (auto st = AttachStimulator(config, bench); !st.ok()) {
    return Fail("stimulator on " + config.stimulator_port, st);
  }

  server::services::SampleHub hub;
  // Every stored parameter set, whoever stored it, is an event for the SSE
  // and DDS subscribers (after its commit; no polling over the legs).
  // (Ended before the database closes, below.)
  std::optional<server::services::ParameterSetEvents> set_events;
  set_events.emplace(**db, hub);
  server::services::RunServiceConfig run_config;
  run_config.time_scale = config.time_scale;
  server::services::RunService runs(**db, *bench, hub, run_config);
  // Before anything can start a run: runs a crash left open end failed,
  // and an e-stop latched before the stop is latched again.
  if (api::Status st = Recover(runs); !st.ok()) return Fail("recovery at start", st);
  server::services::BenchService bench_service(**db, runs, simulated);
  server::services::JobPoolConfig job_config;
  job_config.workers = config.job_workers;
  server::services::JobPool jobs(job_config);
  server::services::IdentificationConfig identification_config;
  identification_config.joint_limits =
      model::JointLimits{bench->limits().min_angle_deg, bench->limits().max_angle_deg};
  server::services::IdentificationService identification(**db, identification_config);
  // Predictions stop at the bench's range of motion, as the knee does.
  server::services::PredictionConfig prediction_config;
  prediction_config.joint_limits =
      model::JointLimits{bench->limits().min_angle_deg, bench->limits().max_angle_deg};
  server::services::PredictionService prediction(**db, prediction_config);
  server::services::ComparisonService comparison(**db, prediction_config);

  // The DDS front end (docs/API.md, "DDS"): the same services, commands through
  // the same RunService calls and audit log as HTTP.
  server::services::CommandService dds_commands(**db, runs, "dds");
  std::unique_ptr<server::dds::DdsServer> dds;
  if (config.dds_transport != "off") {
    auto started = StartDds(config, bench_id, **db, runs, hub, dds_commands);
    if (!started.ok()) return Fail("DDS", started.status());
    dds = std::move(*started);
  }

  server::http::AuthenticatorOptions auth_options;
  auth_options.failed_tokens.burst = config.auth_failure_burst;
  auth_options.failed_tokens.refill_per_s = config.auth_failure_refill_per_s;
  server::http::Authenticator auth(**db, auth_options);
  server::http::StreamSlots slots(static_cast<std::size_t>(config.max_streams));
  server::http::ApiDependencies deps;
  deps.db = db->get();
  deps.auth = &auth;
  deps.streams = &slots;
  deps.backup_dir = (data_dir / "backups").string();
  deps.bench = &bench_service;
  deps.runs = &runs;
  deps.samples = &hub;
  deps.jobs = &jobs;
  deps.identification = &identification;
  deps.prediction = &prediction;
  deps.comparison = &comparison;

  server::http::HttpServerOptions http_options;
  http_options.bind_address = config.bind;
  http_options.port = config.port;
  http_options.tls_cert_path = config.tls_cert;
  http_options.tls_key_path = config.tls_key;
  http_options.max_connections = static_cast<std::size_t>(config.max_connections);
  http_options.max_streams = static_cast<std::size_t>(config.max_streams);
  http_options.web_root = config.web_root;
  server::http::HttpServer http(http_options, server::http::BuildApiRoutes(deps), auth, **db,
                                slots);
  auto port = http.Bind();
  if (!port.ok()) return Fail("cannot listen", port.status());
  // One server per bench (docs/SAFETY.md): a lost bench lock stops the bench
  // and refuses runs; the bench held by another server ends this one.
  std::atomic<bool> bench_taken{false};
  std::optional<server::services::BenchLockGuard> bench_lock;
  bench_lock.emplace(
      **db, runs,
      [&](const std::string&) {
        bench_taken = true;
        http.Stop();
      },
      [](std::string_view line) { std::cerr << "fesbench-server: " << line << std::endl; });

  PrintBanner(config, bench->kind(), db_name, bench_id, token_path, dds.get(), *port);
  // systemd's Type=notify: `systemctl start` returns now that the port
  // answers (the socket listens since Bind; Run accepts what queued).
  sd_notifyf(0, "READY=1\nSTATUS=listening on port %d", *port);

  std::thread waiter([&] {
    int signal = 0;
    sigwait(&signals, &signal);
    http.Stop();
  });
  const bool served = http.Run() && !bench_taken;
  sd_notify(0, "STOPPING=1\nSTATUS=stopping: a running protocol is stopped with stimulation zero");
  if (!served && !bench_taken) std::cerr << "fesbench-server: the HTTP server failed" << std::endl;
  http.Stop();
  // Wake the waiter if the server ended on its own.
  pthread_kill(waiter.native_handle(), SIGTERM);
  waiter.join();

  runs.Shutdown();       // a running protocol: stimulation zero, state aborted, all stored
  if (dds) dds->Stop();  // after the run's final state went out
  hub.Close();
  jobs.Shutdown();
  set_events.reset();
  bench_lock.reset();
  db->reset();
  std::cout << "fesbench-server: stopped" << std::endl;
  return served ? 0 : 1;
}
