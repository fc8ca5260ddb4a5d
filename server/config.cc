#include "server/config.h"

#include <CLI/CLI.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <ostream>
#include <sstream>
#include <string>

#include "api/json_fields.h"
#include "server/database_maintenance.h"

namespace fesbench::server {

api::Status ValidateServerConfig(const ServerConfig& c) {
  if (c.bind.empty()) return api::Status::InvalidArgument("must not be empty", "bind");
  if (c.port < 0 || c.port > 65535)
    return api::Status::InvalidArgument("must be in [0, 65535]", "port");
  if (c.db.empty()) return api::Status::InvalidArgument("must not be empty", "db");
  if (c.bench != "sim" && c.bench != "replay") {
    return api::Status::InvalidArgument("must be sim or replay", "bench");
  }
  if (!std::isfinite(c.time_scale) || c.time_scale < 0 || c.time_scale > 1000) {
    return api::Status::InvalidArgument("must be in [0, 1000]", "time-scale");
  }
  if (!std::isfinite(c.max_stop_impact_deg_s) || c.max_stop_impact_deg_s <= 0 ||
      c.max_stop_impact_deg_s > 2000) {
    return api::Status::InvalidArgument("must be in (0, 2000] deg/s", "max-stop-impact-deg-s");
  }
  if (c.dds_domain < 0 || c.dds_domain > 232) {
    return api::Status::InvalidArgument("must be in [0, 232]", "dds-domain");
  }
  if (c.dds_transport != "auto" && c.dds_transport != "shm" && c.dds_transport != "udp" &&
      c.dds_transport != "udp-loopback" && c.dds_transport != "off") {
    return api::Status::InvalidArgument("must be auto, shm, udp, udp-loopback or off",
                                        "dds-transport");
  }
  if (c.tls_cert.empty() != c.tls_key.empty()) {
    return api::Status::InvalidArgument("--tls-cert and --tls-key go together", "tls-cert");
  }
  if (c.bench == "replay" && c.replay.empty()) {
    return api::Status::InvalidArgument("--bench replay needs at least one --replay CSV file",
                                        "replay");
  }
  if (c.stimulator != "sim" && c.stimulator != "sciencemode2" && c.stimulator != "sciencemode4") {
    return api::Status::InvalidArgument("must be sim, sciencemode2 or sciencemode4", "stimulator");
  }
  if (c.stimulator != "sim" && c.stimulator_port.empty()) {
    return api::Status::InvalidArgument(
        "--stimulator " + c.stimulator + " needs --stimulator-port (e.g. /dev/ttyUSB0)",
        "stimulator-port");
  }
  if (c.stimulator != "sim" && c.time_scale != 1.0) {
    // A device fires in real time whatever the bench's clock does: at another
    // scale it would be sent a whole run's commands too fast (or too slow)
    // and deliver something other than the stored trial says.
    return api::Status::InvalidArgument(
        "must be 1 with --stimulator " + c.stimulator +
            " (a real stimulator runs in real time; other scales are for the simulated one)",
        "time-scale");
  }
  const int channels = c.stimulator == "sciencemode4" ? 4 : 8;
  if (c.stimulator_channel < 1 || c.stimulator_channel > channels) {
    return api::Status::InvalidArgument("must be in [1, " + std::to_string(channels) + "]",
                                        "stimulator-channel");
  }
  if (c.job_workers < 1 || c.job_workers > 64) {
    return api::Status::InvalidArgument("must be in [1, 64]", "job-workers");
  }
  if (c.max_connections < 1 || c.max_connections > 1024) {
    return api::Status::InvalidArgument("must be in [1, 1024]", "max-connections");
  }
  if (c.max_streams < 1 || c.max_streams > 256) {
    return api::Status::InvalidArgument("must be in [1, 256]", "max-streams");
  }
  if (c.auth_failure_burst < 1 || c.auth_failure_burst > 100000) {
    return api::Status::InvalidArgument("must be in [1, 100000]", "auth-failure-burst");
  }
  if (!std::isfinite(c.auth_failure_refill_per_s) || c.auth_failure_refill_per_s <= 0 ||
      c.auth_failure_refill_per_s > 1000) {
    return api::Status::InvalidArgument("must be in (0, 1000]", "auth-failure-refill-per-s");
  }
  if (!c.dds_security.empty() && c.dds_transport == "off") {
    return api::Status::InvalidArgument("--dds-security needs DDS on (--dds-transport is off)",
                                        "dds-security");
  }
  if (!c.dds_profile_name.empty() && c.dds_profile.empty()) {
    return api::Status::InvalidArgument("--dds-profile-name needs --dds-profile",
                                        "dds-profile-name");
  }
  if (c.backup_keep_days < 1 || c.backup_keep_days > 3650) {
    return api::Status::InvalidArgument("must be in [1, 3650] days", "backup-keep-days");
  }
  return api::Status::Ok();
}

std::string DefaultWebRoot() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const std::filesystem::path installed =
        exe.parent_path().parent_path() / "share" / "fesbench" / "web";
    if (std::filesystem::is_regular_file(installed / "index.html", ec)) return installed.string();
  }
#ifdef FESBENCH_DEFAULT_WEB_ROOT
  return FESBENCH_DEFAULT_WEB_ROOT;
#else
  return {};
#endif
}

api::Status ApplyConfigJson(const std::string& json_text, ServerConfig& c) {
  auto json = api::ParseJsonObject(json_text);
  if (!json.ok()) return json.status();
  api::JsonFields f(*json);
  if (auto v = f.String("bind", false, 255)) c.bind = *v;
  if (auto v = f.Integer("port", false, 0, 65535)) c.port = static_cast<int>(*v);
  if (auto v = f.String("db", false, 4096)) c.db = *v;
  if (auto v = f.String("bench-id", false, 255)) c.bench_id = *v;
  if (auto v = f.String("data-dir", false, 4096)) c.data_dir = *v;
  if (auto v = f.String("bench", false, 16)) c.bench = *v;
  if (auto v = f.Number("time-scale", false, 0.0, 1000.0)) c.time_scale = *v;
  if (auto v = f.Number("max-stop-impact-deg-s", false, 0.0, 2000.0)) c.max_stop_impact_deg_s = *v;
  if (auto v = f.Integer("dds-domain", false, 0, 232)) c.dds_domain = static_cast<int>(*v);
  if (auto v = f.String("dds-transport", false, 16)) c.dds_transport = *v;
  if (auto v = f.String("dds-profile", false, 4096)) c.dds_profile = *v;
  if (auto v = f.String("dds-profile-name", false, 255)) c.dds_profile_name = *v;
  if (auto v = f.String("dds-bench-id", false, 255)) c.dds_bench_id = *v;
  if (auto v = f.String("dds-security", false, 4096)) c.dds_security = *v;
  if (auto v = f.String("dds-identity", false, 64)) c.dds_identity = *v;
  if (auto v = f.String("tls-cert", false, 4096)) c.tls_cert = *v;
  if (auto v = f.String("tls-key", false, 4096)) c.tls_key = *v;
  if (auto v = f.Integer("seed", false, 0)) c.seed = static_cast<std::uint64_t>(*v);
  if (const auto* files = f.Any("replay", false)) {
    if (!files->is_array())
      return api::Status::InvalidArgument("must be an array of paths", "replay");
    c.replay.clear();
    for (const auto& file : *files) {
      if (!file.is_string())
        return api::Status::InvalidArgument("must be an array of paths", "replay");
      c.replay.push_back(file.get<std::string>());
    }
  }
  if (auto v = f.String("stimulator", false, 32)) c.stimulator = *v;
  if (auto v = f.String("stimulator-port", false, 4096)) c.stimulator_port = *v;
  if (auto v = f.Integer("stimulator-channel", false, 1, 8))
    c.stimulator_channel = static_cast<int>(*v);
  if (auto v = f.Integer("job-workers", false, 1, 64)) c.job_workers = static_cast<int>(*v);
  if (auto v = f.Integer("max-connections", false, 1, 1024))
    c.max_connections = static_cast<int>(*v);
  if (auto v = f.Integer("max-streams", false, 1, 256)) c.max_streams = static_cast<int>(*v);
  if (auto v = f.Integer("auth-failure-burst", false, 1, 100000))
    c.auth_failure_burst = static_cast<int>(*v);
  if (auto v = f.Number("auth-failure-refill-per-s", false, 0.0, 1000.0))
    c.auth_failure_refill_per_s = *v;
  if (auto v = f.String("web-root", false, 4096)) c.web_root = *v;
  if (auto v = f.Integer("backup-keep-days", false, 1, 3650))
    c.backup_keep_days = static_cast<int>(*v);
  return f.Finish();
}

ParsedConfig ParseServerConfig(int argc, const char* const* argv, std::ostream& out,
                               std::ostream& err) {
  ParsedConfig parsed;
  ServerConfig flags;
  CLI::App app{"fesbench-server: the FES bench service (HTTP/JSON API, docs/API.md)",
               "fesbench-server"};
  app.add_option("--config", flags.config_file, "JSON file with the same keys as the flags")
      ->check(CLI::ExistingFile);
  app.add_option("--bind", flags.bind, "listen address (default 127.0.0.1)");
  app.add_option("--port", flags.port, "TCP port; 0 picks a free one (default 8080)");
  app.add_option("--db", flags.db,
                 "SQLite database file (default ./data/fesbench.db), or a PostgreSQL URL "
                 "postgresql://user@host:port/database shared by several servers");
  app.add_option("--bench-id", flags.bench_id,
                 "this server's bench on a shared database (default: the host name)");
  app.add_option("--data-dir", flags.data_dir,
                 "folder of admin.token and backups (default: the SQLite file's folder, or "
                 "./data with PostgreSQL)");
  app.add_option("--bench", flags.bench, "sim (simulated leg) or replay (CSV trials)")
      ->check(CLI::IsMember({"sim", "replay"}));
  app.add_option("--time-scale", flags.time_scale,
                 "bench seconds per wall second: 1 real time, 0 as fast as possible");
  app.add_option("--max-stop-impact-deg-s", flags.max_stop_impact_deg_s,
                 "model gate: fastest predicted arrival of the knee at a stop of the range of "
                 "motion, deg/s (default " +
                     std::to_string(static_cast<int>(kDefaultBenchMaxStopImpactDegS)) + ")");
  app.add_option("--dds-domain", flags.dds_domain, "DDS domain id (default 0)");
  app.add_option("--dds-transport", flags.dds_transport,
                 "DDS transport: auto (shm + UDP), shm, udp, udp-loopback, off (default auto)")
      ->check(CLI::IsMember({"auto", "shm", "udp", "udp-loopback", "off"}));
  app.add_option("--dds-profile", flags.dds_profile, "Fast DDS XML profile file")
      ->check(CLI::ExistingFile);
  app.add_option("--dds-profile-name", flags.dds_profile_name,
                 "participant profile of --dds-profile to use (default: its default profile)");
  app.add_option("--dds-bench-id", flags.dds_bench_id,
                 "DDS key of this bench's state (default: --bench-id)");
  app.add_option("--dds-security", flags.dds_security,
                 "secured DDS: a lab PKI directory made by scripts/make-dds-pki.sh")
      ->check(CLI::ExistingDirectory);
  app.add_option("--dds-identity", flags.dds_identity,
                 "this server's identity in --dds-security (default server)");
  app.add_option("--tls-cert", flags.tls_cert, "PEM certificate for HTTPS");
  app.add_option("--tls-key", flags.tls_key, "PEM private key for HTTPS");
  app.add_option("--seed", flags.seed, "seed of the simulated virtual subject (default 1)");
  app.add_option("--replay", flags.replay, "CSV trial files for --bench replay");
  app.add_option("--stimulator", flags.stimulator,
                 "sim (the bench's own), sciencemode2 (a RehaStim2) or sciencemode4 (a P24, "
                 "low level) on --stimulator-port")
      ->check(CLI::IsMember({"sim", "sciencemode2", "sciencemode4"}));
  app.add_option("--stimulator-port", flags.stimulator_port,
                 "serial device of the stimulator, e.g. /dev/ttyUSB0");
  app.add_option("--stimulator-channel", flags.stimulator_channel,
                 "stimulator channel: 1-8 on a RehaStim2, 1-4 on a P24 (default 1)");
  app.add_option("--job-workers", flags.job_workers, "identification/prediction worker threads");
  app.add_option("--max-connections", flags.max_connections,
                 "keep-alive connections served at once (default 48)");
  app.add_option("--max-streams", flags.max_streams, "open event streams (default 16)");
  app.add_option("--auth-failure-burst", flags.auth_failure_burst,
                 "failed tokens one address may present at once before 429 (default 30)");
  app.add_option("--auth-failure-refill-per-s", flags.auth_failure_refill_per_s,
                 "failed tokens an address regains per second (default 1)");
  app.add_option("--web-root", flags.web_root,
                 "folder of the built web client served at / (\"\": none)");
  app.add_option("--backup-keep-days", flags.backup_keep_days,
                 "days --backup keeps the backups in <data-dir>/backups (default 14)");
  bool backup = false;
  bool migrate = false;
  auto* backup_flag = app.add_flag(
      "--backup", backup,
      "make an online backup of the database into <data-dir>/backups (SQLite: the backup API, "
      "also while a server runs; PostgreSQL: pg_dump), delete those older than "
      "--backup-keep-days (of the pre-migration ones, all but the newest " +
          std::to_string(kKeptPreMigrationBackups) + "), and exit");
  app.add_flag("--migrate", migrate,
               "back up the stopped server's database, bring it to this version's schema (a "
               "newer schema is refused) and exit")
      ->excludes(backup_flag);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    parsed.exit_code = app.exit(e, out, err);
    return parsed;
  } catch (const CLI::ParseError& e) {
    app.exit(e, out, err);
    parsed.exit_code = 2;
    return parsed;
  }

  ServerConfig config;
  if (!flags.config_file.empty()) {
    std::ifstream in(flags.config_file);
    std::stringstream text;
    text << in.rdbuf();
    if (!in) {
      err << "fesbench-server: cannot read " << flags.config_file << "\n";
      parsed.exit_code = 2;
      return parsed;
    }
    if (auto st = ApplyConfigJson(text.str(), config); !st.ok()) {
      err << "fesbench-server: " << flags.config_file << ": " << st.ToString() << "\n";
      parsed.exit_code = 2;
      return parsed;
    }
    config.config_file = flags.config_file;
  }
  auto given = [&](const char* name) { return app.count(name) > 0; };
  if (given("--bind")) config.bind = flags.bind;
  if (given("--port")) config.port = flags.port;
  if (given("--db")) config.db = flags.db;
  if (given("--bench-id")) config.bench_id = flags.bench_id;
  if (given("--data-dir")) config.data_dir = flags.data_dir;
  if (given("--bench")) config.bench = flags.bench;
  if (given("--time-scale")) config.time_scale = flags.time_scale;
  if (given("--max-stop-impact-deg-s")) config.max_stop_impact_deg_s = flags.max_stop_impact_deg_s;
  if (given("--dds-domain")) config.dds_domain = flags.dds_domain;
  if (given("--dds-transport")) config.dds_transport = flags.dds_transport;
  if (given("--dds-profile")) config.dds_profile = flags.dds_profile;
  if (given("--dds-profile-name")) config.dds_profile_name = flags.dds_profile_name;
  if (given("--dds-bench-id")) config.dds_bench_id = flags.dds_bench_id;
  if (given("--dds-security")) config.dds_security = flags.dds_security;
  if (given("--dds-identity")) config.dds_identity = flags.dds_identity;
  if (given("--tls-cert")) config.tls_cert = flags.tls_cert;
  if (given("--tls-key")) config.tls_key = flags.tls_key;
  if (given("--seed")) config.seed = flags.seed;
  if (given("--replay")) config.replay = flags.replay;
  if (given("--stimulator")) config.stimulator = flags.stimulator;
  if (given("--stimulator-port")) config.stimulator_port = flags.stimulator_port;
  if (given("--stimulator-channel")) config.stimulator_channel = flags.stimulator_channel;
  if (given("--job-workers")) config.job_workers = flags.job_workers;
  if (given("--max-connections")) config.max_connections = flags.max_connections;
  if (given("--max-streams")) config.max_streams = flags.max_streams;
  if (given("--web-root")) config.web_root = flags.web_root;
  if (given("--backup-keep-days")) config.backup_keep_days = flags.backup_keep_days;
  if (backup) config.task = ServerTask::kBackup;
  if (migrate) config.task = ServerTask::kMigrate;
  if (given("--auth-failure-burst")) config.auth_failure_burst = flags.auth_failure_burst;
  if (given("--auth-failure-refill-per-s"))
    config.auth_failure_refill_per_s = flags.auth_failure_refill_per_s;

  if (auto st = ValidateServerConfig(config); !st.ok()) {
    err << "fesbench-server: " << st.ToString() << "\n";
    parsed.exit_code = 2;
    return parsed;
  }
  parsed.config = std::move(config);
  return parsed;
}

}  // namespace fesbench::server
