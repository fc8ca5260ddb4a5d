#pragma once

// Runs the real fesbench-server binary for integration tests: a temporary
// database, --port 0 (the port is read from the "listening on" line),
// --time-scale 0; stopped by pid with SIGTERM, exit status checked by the
// caller, or by the destructor (a server still running there gets SIGTERM and
// must exit 0, else the test fails). Also a raw-socket helper for requests httplib::Client cannot make
// (chunked bodies, thousands of headers, unknown methods).

#include <httplib.h>

#include <chrono>
#include <functional>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

namespace fesbench::testing {

class ServerProcess {
 public:
  /// Starts the server with `extra_args` appended; throws std::runtime_error
  /// if it does not print its port within `timeout`.
  explicit ServerProcess(std::vector<std::string> extra_args = {},
                         std::chrono::seconds timeout = std::chrono::seconds(20));
  /// Starts a server on the data folder of `previous` (which must be
  /// stopped); the folder stays owned by `previous`.
  static std::unique_ptr<ServerProcess> Restart(const ServerProcess& previous);
  /// If still running: SIGTERM, and a test failure unless the server exits
  /// with 0 within 20 s (SIGKILL then). Removes the temporary folder.
  ~ServerProcess();
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  int port() const { return port_; }
  /// The server's process id while it runs (−1 once stopped).
  int pid() const { return pid_; }
  const std::string& admin_token() const { return admin_token_; }
  const std::filesystem::path& dir() const { return dir_; }
  std::filesystem::path db_path() const { return dir_ / "data" / "fesbench.db"; }
  /// Everything the server wrote to stderr (stderr.log in dir()).
  std::string Stderr() const;
  /// Everything the server printed on stdout so far.
  const std::string& output() const { return output_; }

  /// SIGTERM, then waits up to `timeout`; the exit code (−1 on timeout or a
  /// signal death).
  int Terminate(std::chrono::seconds timeout = std::chrono::seconds(20));
  /// Waits up to `timeout` for the server to exit on its own (no signal);
  /// its exit code (−1 for a death by signal), or nullopt if it still runs.
  std::optional<int> AwaitExit(std::chrono::seconds timeout);
  /// SIGKILL (a crash: no clean-up of any kind), then waits for the process.
  void Kill();

  /// A client for this server (5 s timeouts).
  httplib::Client Client() const;

 private:
  ServerProcess(std::filesystem::path dir, std::vector<std::string> extra_args, bool owns_dir,
                std::chrono::seconds timeout);

  /// Waits up to `timeout` for the process (draining stdout); its wait
  /// status, or nullopt if it is still running.
  std::optional<int> WaitExit(std::chrono::seconds timeout);
  /// SIGTERM and wait; empty if it exited with 0, else how it ended.
  std::string Stop(std::chrono::seconds timeout);

  std::filesystem::path dir_;
  bool owns_dir_ = true;
  int pid_ = -1;
  int stdout_fd_ = -1;
  int port_ = 0;
  std::string admin_token_;
  std::string output_;
};

/// A fesbench-server that is expected not to start: run with exactly `args`
/// until it exits (SIGKILL after `timeout`).
struct ExitedServer {
  int exit_code = -1;     ///< −1: killed at the timeout, or a death by signal.
  std::string output;     ///< stdout.
  std::string error;      ///< stderr.
  double elapsed_ms = 0;  ///< from the start to its exit.
};
ExitedServer RunServerToExit(const std::vector<std::string>& args,
                             std::chrono::seconds timeout = std::chrono::seconds(20));

/// A request with a JSON body (or none when body is null), with a bearer
/// token when `token` is not empty. Returns status and parsed body (null if
/// the body is not JSON); status −1 when the connection failed.
struct JsonResponse {
  int status = -1;
  nlohmann::json body;
  std::string text;
  httplib::Headers headers;
};
JsonResponse Call(httplib::Client& client, const std::string& method, const std::string& path,
                  const std::string& token, const nlohmann::json& body = nullptr,
                  const std::string& content_type = "application/json");

/// Sends raw bytes on a new loopback connection and returns what came back
/// until the server closes or `timeout` passes.
std::string RawExchange(int port, const std::string& request,
                        std::chrono::milliseconds timeout = std::chrono::milliseconds(3000));
/// The status code of a raw HTTP response ("HTTP/1.1 411 ..."), or −1.
int RawStatus(const std::string& response);

/// Milliseconds since `start` on the steady clock (latencies the tests print).
inline double MsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

/// Polls GET /jobs/{id} until the job is done or failed and returns it (its
/// error body if the job cannot be read; null after 60 s).
nlohmann::json WaitForJob(httplib::Client& client, const std::string& token, std::int64_t id);

/// Starts `request` (POST /sessions/{id}/runs) and runs it to its end,
/// heart-beating it; returns the run's view (null, with a test failure,
/// after 60 s).
nlohmann::json RunToEnd(httplib::Client& client, const std::string& token,
                        std::int64_t session_id, const nlohmann::json& request);

/// Creates a user with `role` and returns a token for it (admin token used).
std::string CreateUserToken(httplib::Client& client, const std::string& admin_token,
                            const std::string& name, const std::string& role);

}  // namespace fesbench::testing

namespace fesbench::testing {

/// A raw loopback connection for protocol-edge tests (half-close,
/// pipelining, slow clients). Closed by the destructor.
class RawConnection {
 public:
  explicit RawConnection(int port);
  ~RawConnection();
  RawConnection(const RawConnection&) = delete;
  RawConnection& operator=(const RawConnection&) = delete;

  bool ok() const { return fd_ >= 0; }
  int fd() const { return fd_; }
  /// Sends all of `bytes`; false if the connection failed.
  bool Send(const std::string& bytes);
  /// shutdown(SHUT_WR): the request is complete, nothing more comes.
  void HalfClose();
  /// Reads until `done(received)` is true, the server closes, or `timeout`.
  std::string ReadUntil(const std::function<bool(const std::string&)>& done,
                        std::chrono::milliseconds timeout);
  /// Whether the server has closed this connection (a FIN or reset is
  /// waiting); does not consume data.
  bool ClosedByPeer();

 private:
  int fd_ = -1;
};

/// The number of HTTP responses in `bytes` (status lines of whole
/// responses framed by Content-Length).
int CountResponses(const std::string& bytes);

}  // namespace fesbench::testing
