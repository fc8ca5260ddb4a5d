#include "tests/support/postgres_server.h"

#include <arpa/inet.h>
#include <libpq-fe.h>
#include <netinet/in.h>
#include <pwd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <mutex>
#include <random>
#include <sstream>
#include <vector>

namespace fesbench::testing {
namespace {

namespace fs = std::filesystem;

// A loopback port nobody listens on right now (the server may still lose
// it to a race; Start then tries another).
int FreePort() {
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

std::string Quoted(const std::string& text) { return "'" + text + "'"; }

// Runs `command` (as the postgres user when we are root); its exit status.
int RunAsServerUser(const std::string& command) {
  const std::string line =
      ::geteuid() == 0 ? "runuser -u postgres -- sh -c " + Quoted(command) : command;
  return std::system((line + " >/dev/null 2>&1").c_str());
}

std::string ReadFile(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

api::Status Exec(const std::string& url, const std::string& sql) {
  PGconn* conn = PQconnectdb(url.c_str());
  if (PQstatus(conn) != CONNECTION_OK) {
    std::string error = PQerrorMessage(conn);
    PQfinish(conn);
    return api::Status::Unavailable("cannot connect to " + url + ": " + error);
  }
  PGresult* result = PQexec(conn, sql.c_str());
  const bool ok = PQresultStatus(result) == PGRES_COMMAND_OK;
  std::string error = ok ? "" : PQerrorMessage(conn);
  PQclear(result);
  PQfinish(conn);
  if (!ok) return api::Status::Internal(sql + ": " + error);
  return api::Status::Ok();
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
    if (!name.empty() && std::all_of(name.begin(), name.end(), ::isdigit) &&
        fs::exists(entry.path() / "bin" / "initdb")) {
      versions.push_back(std::stoi(name));
    }
  }
  if (!versions.empty()) {
    return "/usr/lib/postgresql/" + std::to_string(*std::max_element(versions.begin(), versions.end())) +
           "/bin";
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

api::Result<std::unique_ptr<PostgresServer>> PostgresServer::Start(const fs::path& dir) {
  const std::string bin = BinDir();
  if (bin.empty()) {
    return api::Status::Unavailable(
        "PostgreSQL server binaries not found (install postgresql-15: scripts/setup.sh does)");
  }
  std::error_code ec;
  fs::remove_all(dir, ec);
  fs::create_directories(dir);
  if (::geteuid() == 0) {
    const passwd* user = ::getpwnam("postgres");
    if (user == nullptr) {
      return api::Status::Unavailable("running as root and there is no postgres user to run "
                                      "the server as (install postgresql-15)");
    }
    if (::chown(dir.c_str(), user->pw_uid, user->pw_gid) != 0) {
      return api::Status::Unavailable("cannot give " + dir.string() + " to the postgres user");
    }
  }
  const std::string data = (dir / "data").string();
  const std::string log = (dir / "log").string();
  // A throwaway cluster: trust on loopback, C locale (byte order, like the
  // schema asks anyway).
  if (RunAsServerUser(bin + "/initdb -D " + data + " -U postgres --auth=trust -E UTF8 --locale=C") !=
      0) {
    return api::Status::Unavailable("initdb failed in " + data);
  }
  for (int attempt = 0; attempt < 5; ++attempt) {
    const int port = FreePort();
    // fsync off: this cluster is thrown away with the test; the durability
    // of acknowledged writes is PostgreSQL's own, not under test here.
    const std::string options = "-c listen_addresses=127.0.0.1 -p " + std::to_string(port) +
                                " -c unix_socket_directories=" + dir.string() +
                                " -c fsync=off -c synchronous_commit=off"
                                " -c full_page_writes=off -c max_connections=300";
    const std::string start =
        bin + "/pg_ctl -D " + data + " -l " + log + " -w -t 60 -o \"" + options + "\" start";
    if (RunAsServerUser(start) == 0) {
      return std::unique_ptr<PostgresServer>(new PostgresServer(dir, port));
    }
  }
  return api::Status::Unavailable("the PostgreSQL server did not start: " + ReadFile(log));
}

PostgresServer::~PostgresServer() {
  if (!detached_) StopIn(dir_);
}

void PostgresServer::StopIn(const fs::path& dir) {
  const std::string bin = BinDir();
  if (!bin.empty() && fs::exists(dir / "data" / "postmaster.pid")) {
    RunAsServerUser(bin + "/pg_ctl -D " + (dir / "data").string() + " -m fast -w stop");
  }
  std::error_code ec;
  fs::remove_all(dir, ec);
}

std::string PostgresServer::Url(const std::string& database) const {
  return "postgresql://postgres@127.0.0.1:" + std::to_string(port_) + "/" + database;
}

api::Status CreateDatabase(const std::string& base_url, const std::string& name) {
  return Exec(base_url + "postgres", "CREATE DATABASE \"" + name + "\"");
}

api::Status DropDatabase(const std::string& base_url, const std::string& name) {
  return Exec(base_url + "postgres", "DROP DATABASE IF EXISTS \"" + name + "\" WITH (FORCE)");
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
    const std::string url = ReadFile(fs::path(dir) / "url");
    if (!url.empty()) {
      shared.base_url = url.substr(0, url.find('\n'));
      return shared;
    }
  }
  const fs::path dir =
      fs::temp_directory_path() / ("fesbench_pg_" + std::to_string(::getpid()));
  shared.binaries_missing = PostgresServer::BinDir().empty();
  auto started = PostgresServer::Start(dir);
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
  name_ = "fesbench_t_" + std::to_string(::getpid()) + "_" + std::to_string(counter++) + "_" +
          std::to_string(random() % 100000);
  if (auto status = CreateDatabase(base_url_, name_); !status.ok()) {
    skip_reason_ = "cannot create a scratch database: " + status.ToString();
    name_.clear();
    return;
  }
  url_ = base_url_ + name_;
}

ScratchDatabase::~ScratchDatabase() {
  if (!name_.empty()) (void)DropDatabase(base_url_, name_);
}

}  // namespace fesbench::testing
