#pragma once

/// @file
/// fesbench-server's settings (README, "Running the server"): command-line flags and, with
/// the same keys, an optional JSON config file (--config FILE). Flags
/// override the file; the file overrides the defaults. Only the executable
/// reads these; the libraries take the plain structs built from them.

#include <cstdint>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include "api/status.h"
#include "server/bench/bench.h"

namespace fesbench::server {

/// The bundled web client: installed, `<prefix>/share/fesbench/web` beside
/// the executable's `<prefix>/bin` (the Debian package's
/// /usr/share/fesbench/web) when it holds an index.html; otherwise where the
/// build put it (clients/web → <build>/clients/web/dist).
std::string DefaultWebRoot();

/// What the server is started for: to serve, or one maintenance step on its
/// database that then exits (the Debian package's backup timer and
/// maintainer scripts, README "Install on a lab PC").
enum class ServerTask {
  kServe,
  /// --backup: an online backup into <data-dir>/backups, also while a server
  /// runs on the database; backups older than backup-keep-days are deleted,
  /// of the pre-migration ones all but the newest 5.
  kBackup,
  /// --migrate: the database backed up, then brought to this software's
  /// schema; a newer schema is refused, naming it. Needs the server stopped.
  kMigrate,
};

struct ServerConfig {
  std::string bind = "127.0.0.1";         ///< --bind: listen address.
  int port = 8080;                        ///< --port: 0 picks a free port (printed).
  /// --db: an SQLite file (folder created), or a PostgreSQL URL
  /// (postgresql://user@host:port/database) that several servers may share.
  std::string db = "./data/fesbench.db";
  /// --bench-id: this server's bench on a shared database (its runs and
  /// e-stop latch); default: the host name. Also the DDS bench key.
  std::string bench_id;
  /// --data-dir: the folder of admin.token and backups/ (default: the SQLite
  /// file's folder, or ./data with PostgreSQL).
  std::string data_dir;
  std::string bench = "sim";              ///< --bench: "sim" or "replay".
  double time_scale = 1.0;                ///< --time-scale: 1 real time, 0 as fast as possible.
  /// --max-stop-impact-deg-s: the model gate's limit on the predicted speed
  /// of the knee at a stop of the range of motion (BenchLimits), (0, 2000].
  double max_stop_impact_deg_s = kDefaultBenchMaxStopImpactDegS;
  int dds_domain = 0;  ///< --dds-domain: 0–232 (DDS front end, docs/API.md).
  /// --dds-transport: auto (Fast DDS default: shm + UDP), shm, udp,
  /// udp-loopback, or off (no DDS front end).
  std::string dds_transport = "auto";
  std::string dds_profile;  ///< --dds-profile: Fast DDS XML profile file.
  /// --dds-profile-name: the participant profile of that file to create the
  /// participant from ("" = the file's default participant profile).
  std::string dds_profile_name;
  std::string dds_bench_id;  ///< --dds-bench-id: key of the bench state (default: --bench-id).
  /// --dds-security: a lab PKI directory (scripts/make-dds-pki.sh); secured
  /// DDS (authentication, encryption, access control) when set.
  std::string dds_security;
  std::string dds_identity = "server";  ///< --dds-identity: this server's identity in it.
  std::string tls_cert;                 ///< --tls-cert: PEM certificate (with --tls-key: HTTPS).
  std::string tls_key;                  ///< --tls-key: PEM private key.
  std::uint64_t seed = 1;               ///< --seed: virtual subject of the simulated bench.
  std::vector<std::string> replay;      ///< --replay: CSV trials for --bench replay.
  /// --stimulator: "sim" (the bench's own), "sciencemode2" (a RehaStim2) or
  /// "sciencemode4" (a P24, low level) on --stimulator-port, composed with
  /// the bench's sensors and motor.
  std::string stimulator = "sim";
  std::string stimulator_port;  ///< --stimulator-port: serial device, e.g. /dev/ttyUSB0.
  int stimulator_channel = 1;   ///< --stimulator-channel: 1–8 (RehaStim2), 1–4 (P24).
  int job_workers = 2;                  ///< --job-workers: identification/prediction threads.
  int max_connections = 48;             ///< --max-connections: connections served at once.
  int max_streams = 16;                 ///< --max-streams: open event streams.
  /// --auth-failure-burst: failed tokens one client address may present at
  /// once before it is slowed down (429 with Retry-After), 1–100000.
  int auth_failure_burst = 30;
  /// --auth-failure-refill-per-s: failed tokens an address regains per second, (0, 1000].
  double auth_failure_refill_per_s = 1.0;
  /// --web-root: the web client's built files, served at / (default: the
  /// build tree's clients/web/dist; "" serves none).
  std::string web_root = DefaultWebRoot();
  std::string config_file;  ///< --config: the JSON file read, if any.
  ServerTask task = ServerTask::kServe;  ///< --backup, --migrate: a maintenance step.
  /// --backup-keep-days: how long --backup keeps backups, 1–3650 days.
  int backup_keep_days = 14;
};

/// The outcome of parsing: a config to run with, or an exit code (after
/// --help, or an error already printed).
struct ParsedConfig {
  ServerConfig config;
  std::optional<int> exit_code;
};

/// Parses flags (CLI11) and the optional JSON config file. Errors (unknown
/// flag or key, wrong type, out-of-range value) are printed to `err` and
/// give exit code 2; --help prints to `out` and gives 0.
ParsedConfig ParseServerConfig(int argc, const char* const* argv, std::ostream& out,
                               std::ostream& err);

/// Applies a JSON config object's keys ("bind", "port", "db", "bench",
/// "time-scale", "max-stop-impact-deg-s", "dds-domain", "dds-transport", "dds-profile",
/// "dds-profile-name", "dds-bench-id", "dds-security", "dds-identity", "tls-cert", "tls-key",
/// "seed", "replay", "stimulator", "stimulator-port", "stimulator-channel", "job-workers", "max-connections", "max-streams", "auth-failure-burst",
/// "auth-failure-refill-per-s", "web-root", "backup-keep-days") to `config`. kInvalidArgument naming the key for unknown keys,
/// wrong types and out-of-range values.
api::Status ApplyConfigJson(const std::string& json_text, ServerConfig& config);

/// Range checks shared by flags and file (kInvalidArgument naming the key).
api::Status ValidateServerConfig(const ServerConfig& config);

}  // namespace fesbench::server
