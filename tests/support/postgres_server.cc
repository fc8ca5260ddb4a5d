#include "tests/support/postgres_server.h"

#include <arpa/inet.h>
#include <libpq-fe.h>
#include <netinet/in.h>
#include <pwd.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <mutex>
#include <random>
#include <sstream>
#include <vector>

// File-local names carry a Pg prefix: this file may share a unity batch.
namespace fesbench::testing {
namespace {

namespace fs = std::filesystem;

// The lazily started server of a test process lives in
// <temp>/fesbench_pg_<pid> (SharedPostgresServer).
constexpr const char* kPgOwnDirPrefix = "fesbench_pg_";

// A loopback port nobody listens on right now (the server may still lose
// it to a race; Start then tries another).
int PgFreePort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return 0;
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  address.sin_port = 0;
  socklen_t length = sizeof address;
  int port = 0;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0 &&
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) == 0) {
    port = ntohs(address.sin_port);
  }
  ::close(fd);
  return port;
}

// `text` as one sh word.
std::string PgShellQuote(const std::string& text) {
  std::string quoted = "'";
  for (const char c : text) {
    if (c == '\'') {
      quoted += "'\\''";
    } else {
      quoted += c;
    }
  }
  return quoted + "'";
}

// Runs `args` (as the postgres user when we are root: initdb and postgres
// refuse to run as root) with stdout and stderr to `output` (/dev/null if
// empty); its exit status.
int PgRunAsServerUser(const std::vector<std::string>& args, const fs::path& output = {}) {
  std::string line = ::geteuid() == 0 ? "runuser -u postgres --" : "";
  for (const std::string& arg : args) {
    if (!line.empty()) line += ' ';
    line += PgShellQuote(arg);
  }
  line += " >" + (output.empty() ? std::string("/dev/null") : PgShellQuote(output.string())) +
          " 2>&1 </dev/null";
  return std::system(line.c_str());
}

std::string PgReadFile(const fs::path& path, std::streamoff from = 0) {
  std::ifstream in(path);
  if (from > 0) in.seekg(from);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

std::streamoff PgFileSize(const fs::path& path) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  return ec ? 0 : static_cast<std::streamoff>(size);
}

// One statement on `url`, its own connection.
api::Status PgExec(const std::string& url, const std::string& sql) {
  const char* keys[] = {"dbname", "connect_timeout", nullptr};
  const char* values[] = {url.c_str(), "10", nullptr};
  PGconn* conn = PQconnectdbParams(keys, values, /*expand_dbname=*/1);
  if (PQstatus(conn) != CONNECTION_OK) {
    std::string error = PQerrorMessage(conn);
    PQfinish(conn);
    return api::Status::Unavailable("cannot connect to " + url + ": " + error);
  }
  // No "NOTICE: database … does not exist, skipping" on stderr.
  PQsetNoticeProcessor(conn, [](void*, const char*) {}, nullptr);
  PGresult* result = PQexec(conn, sql.c_str());
  const bool ok = PQresultStatus(result) == PGRES_COMMAND_OK;
  const char* state = PQresultErrorField(result, PG_DIAG_SQLSTATE);
  const std::string sqlstate = state != nullptr ? state : "";
  std::string error = ok ? "" : PQerrorMessage(conn);
  PQclear(result);
  PQfinish(conn);
  if (ok) return api::Status::Ok();
  while (!error.empty() && error.back() == '\n') error.pop_back();
  if (sqlstate == "42P04") return api::Status::AlreadyExists(sql + ": " + error);  // duplicate_database
  return api::Status::Internal(sql + ": " + error);
}

// Stops the postmaster of `data` if one runs (its pid file is there).
void PgStopCluster(const std::string& bin, const fs::path& data, const char* mode) {
  if (!bin.empty() && fs::exists(data / "postmaster.pid")) {
    PgRunAsServerUser({bin + "/pg_ctl", "-D", data.string(), "-m", mode, "-w", "stop"});
  }
}

// Servers that test processes started for themselves and left behind when
// they died without running their exit handlers (a crash, a ctest timeout):
// <temp>/fesbench_pg_<pid>[_<anything>] whose process is gone.
void PgStopOrphans(const fs::path& temp) {
  std::error_code ec;
  const std::string prefix = kPgOwnDirPrefix;
  std::vector<fs::path> orphans;
  for (const auto& entry : fs::directory_iterator(temp, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(prefix, 0) != 0) continue;
    const char* digits = name.c_str() + prefix.size();
    char* end = nullptr;
    const long pid = std::strtol(digits, &end, 10);
    if (end == digits || (*end != '\0' && *end != '_')) continue;
    if (pid <= 0 || pid == ::getpid()) continue;
    if (::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM) continue;  // still alive
    orphans.push_back(entry.path());
  }
  for (const fs::path& orphan : orphans) PostgresServer::StopIn(orphan);
}

}  // namespace

std::string PostgresServer::BinDir() {
  if (const char* env = std::getenv("FESBENCH_PG_BIN"); env != nullptr && *env != '\0') {
    return fs::exists(fs::path(env) / "initdb") ? env : "";
  }
  std::vector<int> versions;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator("/usr/lib/postgresql", ec)) {
    const std::string name = entry.path().filename().string();
    if (!name.empty() &&
        std::all_of(name.begin(), name.end(),
                    [](unsigned char c) { return std::isdigit(c) != 0; }) &&
        fs::exists(entry.path() / "bin" / "initdb")) {
      versions.push_back(std::stoi(name));
    }
  }
  if (!versions.empty()) {
    return "/usr/lib/postgresql/" +
           std::to_string(*std::max_element(versions.begin(), versions.end())) + "/bin";
  }
  if (FILE* pipe = ::popen("pg_config --bindir 2>/dev/null", "r"); pipe != nullptr) {
    char buffer[512] = {};
    std::string dir = std::fgets(buffer, sizeof buffer, pipe) != nullptr ? buffer : "";
    ::pclose(pipe);
    while (!dir.empty() && (dir.back() == '\n' || dir.back() == ' ')) dir.pop_back();
    if (!dir.empty() && fs::exists(fs::path(dir) / "initdb")) return dir;
  }
  return "";
}

api::Result<std::unique_ptr<PostgresServer>> PostgresServer::Start(const fs::path& dir_in) {
  const std::string bin = BinDir();
  if (bin.empty()) return api::Status::Unavailable(std::string(kBinariesMissing));
  std::error_code ec;
  const fs::path dir = fs::absolute(dir_in, ec);
  if (ec) return api::Status::Unavailable("bad server folder " + dir_in.string());
  fs::remove_all(dir, ec);
  if (fs::create_directories(dir, ec); ec) {
    return api::Status::Unavailable("cannot create " + dir.string() + ": " + ec.message());
  }
  if (::geteuid() == 0) {
    const passwd* user = ::getpwnam("postgres");
    if (user == nullptr) {
      return api::Status::Unavailable(
          "running as root and there is no postgres user to run the server as (install "
          "postgresql-15)");
    }
    if (::chown(dir.c_str(), user->pw_uid, user->pw_gid) != 0) {
      return api::Status::Unavailable("cannot give " + dir.string() + " to the postgres user");
    }
  }
  const fs::path data = dir / "data";
  const fs::path log = dir / "log";
  // A throwaway cluster: trust on loopback, C locale (byte order, like the
  // schema asks anyway), --no-sync (initdb in 0.8 s instead of 3.7 s).
  const fs::path initdb_log = dir / "initdb.log";
  if (PgRunAsServerUser({bin + "/initdb", "-D", data.string(), "-U", "postgres", "--auth=trust",
                         "-E", "UTF8", "--locale=C", "--no-sync"},
                        initdb_log) != 0) {
    return api::Status::Unavailable("initdb failed in " + data.string() + ": " +
                                    PgReadFile(initdb_log));
  }
  // The server's Unix socket goes into `dir` unless its path would be over
  // the 107-byte limit; the tests connect over TCP only.
  const std::string socket_dir =
      (dir / ".s.PGSQL.65535").string().size() < 100 ? dir.string() : std::string();
  std::string last_log;
  for (int attempt = 0; attempt < 5; ++attempt) {
    const int port = PgFreePort();
    if (port == 0) return api::Status::Unavailable("no free loopback port");
    // fsync, synchronous_commit and full_page_writes off: this cluster is
    // thrown away with the test run, so a crash needs no recovery; never do
    // this with data that matters. max_connections: parallel test processes
    // each open a writer, readers and a listener per database.
    const std::string options = "-c listen_addresses=127.0.0.1 -p " + std::to_string(port) +
                                " -c unix_socket_directories=" + PgShellQuote(socket_dir) +
                                " -c fsync=off -c synchronous_commit=off"
                                " -c full_page_writes=off -c max_connections=300";
    const std::streamoff log_start = PgFileSize(log);
    if (PgRunAsServerUser({bin + "/pg_ctl", "-D", data.string(), "-l", log.string(), "-w", "-t",
                           "60", "-o", options, "start"}) == 0) {
      return std::unique_ptr<PostgresServer>(new PostgresServer(dir, port));
    }
    last_log = PgReadFile(log, log_start);
    // Gone (or never up) unless it is hanging: make sure, then retry only
    // when another process took the port in between.
    PgStopCluster(bin, data, "immediate");
    if (last_log.find("Address already in use") == std::string::npos) break;
  }
  return api::Status::Unavailable("the PostgreSQL server in " + dir.string() +
                                  " did not start: " + last_log);
}

PostgresServer::PostgresServer(std::filesystem::path dir, int port)
    : dir_(std::move(dir)), port_(port), owner_pid_(::getpid()) {}

PostgresServer::~PostgresServer() {
  // Not in a forked child that exits through the exit handlers: the server
  // is its parent's.
  if (!detached_ && ::getpid() == owner_pid_) StopIn(dir_);
}

void PostgresServer::StopIn(const fs::path& dir) {
  PgStopCluster(BinDir(), dir / "data", "fast");
  std::error_code ec;
  fs::remove_all(dir, ec);
}

std::string PostgresServer::Url(const std::string& database) const {
  return "postgresql://postgres@127.0.0.1:" + std::to_string(port_) + "/" + database;
}

api::Status CreateDatabase(const std::string& base_url, const std::string& name) {
  return PgExec(base_url + "postgres", "CREATE DATABASE \"" + name + "\"");
}

api::Status DropDatabase(const std::string& base_url, const std::string& name) {
  return PgExec(base_url + "postgres", "DROP DATABASE IF EXISTS \"" + name + "\" WITH (FORCE)");
}

const SharedPostgres& SharedPostgresServer() {
  static std::mutex mutex;
  static SharedPostgres shared;
  static bool resolved = false;
  static std::unique_ptr<PostgresServer> own;  // stopped at exit
  std::lock_guard lock(mutex);
  if (resolved) return shared;
  resolved = true;
  if (const char* dir = std::getenv("FESBENCH_TEST_PG_DIR"); dir != nullptr && *dir != '\0') {
    const std::string url = PgReadFile(fs::path(dir) / "url");
    if (!url.empty()) {
      shared.base_url = url.substr(0, url.find('\n'));
      return shared;
    }
  }
  shared.binaries_missing = PostgresServer::BinDir().empty();
  if (shared.binaries_missing) {
    shared.skip_reason = std::string(kBinariesMissing);
    return shared;
  }
  const fs::path temp = fs::temp_directory_path();
  PgStopOrphans(temp);
  auto started = PostgresServer::Start(temp / (kPgOwnDirPrefix + std::to_string(::getpid())));
  if (!started.ok()) {
    shared.skip_reason = started.status().message();
    return shared;
  }
  own = std::move(*started);
  shared.base_url = own->Url("");
  return shared;
}

ScratchDatabase::ScratchDatabase() {
  const SharedPostgres& server = SharedPostgresServer();
  if (server.base_url.empty()) {
    skip_reason_ = server.skip_reason;
    binaries_missing_ = server.binaries_missing;
    return;
  }
  static std::atomic<int> counter{0};
  std::random_device random;
  base_url_ = server.base_url;
  const std::string name = "fesbench_t_" + std::to_string(::getpid()) + "_" +
                           std::to_string(counter++) + "_" + std::to_string(random() % 100000);
  if (auto status = CreateDatabase(base_url_, name); !status.ok()) {
    skip_reason_ = "cannot create a scratch database: " + status.ToString();
    return;
  }
  name_ = name;
  url_ = base_url_ + name_;
}

ScratchDatabase::~ScratchDatabase() {
  if (!name_.empty()) (void)DropDatabase(base_url_, name_);
}

}  // namespace fesbench::testing
