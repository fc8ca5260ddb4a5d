#include "server_process.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <optional>
#include <random>
#include <regex>
#include <stdexcept>
#include <thread>

#ifndef FESBENCH_SERVER_BINARY
#error "FESBENCH_SERVER_BINARY must name the fesbench-server executable"
#endif

namespace fesbench::testing {

namespace {
std::filesystem::path NewTempDir() {
  std::random_device rd;
  auto dir = std::filesystem::temp_directory_path() /
             ("fesbench-http-" + std::to_string(::getpid()) + "-" + std::to_string(rd()));
  std::filesystem::create_directories(dir);
  return dir;
}
}  // namespace

ServerProcess::ServerProcess(std::vector<std::string> extra_args, std::chrono::seconds timeout)
    : ServerProcess(NewTempDir(), std::move(extra_args), true, timeout) {}

std::unique_ptr<ServerProcess> ServerProcess::Restart(const ServerProcess& previous) {
  return std::unique_ptr<ServerProcess>(
      new ServerProcess(previous.dir_, {}, false, std::chrono::seconds(20)));
}

ServerProcess::ServerProcess(std::filesystem::path dir, std::vector<std::string> extra_args,
                             bool owns_dir, std::chrono::seconds timeout)
    : dir_(std::move(dir)), owns_dir_(owns_dir) {
  // Defaults, unless extra_args gives the same flag.
  std::vector<std::string> args = {FESBENCH_SERVER_BINARY};
  const std::pair<std::string, std::string> defaults[] = {
      {"--port", "0"},
      {"--db", db_path().string()},
      {"--data-dir", (dir_ / "data").string()},
      {"--time-scale", "0"},
      // HTTP tests need no DDS participant: keep parallel test servers off
      // domain 0 and out of /dev/shm (the DDS tests use their own domains).
      {"--dds-transport", "off"}};
  for (const auto& [flag, value] : defaults) {
    if (std::find(extra_args.begin(), extra_args.end(), flag) == extra_args.end()) {
      args.push_back(flag);
      args.push_back(value);
    }
  }
  args.insert(args.end(), extra_args.begin(), extra_args.end());

  int pipe_fds[2];
  if (::pipe(pipe_fds) != 0) throw std::runtime_error("pipe failed");
  pid_ = ::fork();
  if (pid_ < 0) throw std::runtime_error("fork failed");
  if (pid_ == 0) {
    ::dup2(pipe_fds[1], STDOUT_FILENO);
    const int err = ::open((dir_ / "stderr.log").c_str(), O_WRONLY | O_CREAT | O_APPEND, 0600);
    if (err >= 0) ::dup2(err, STDERR_FILENO);
    ::close(pipe_fds[0]);
    ::close(pipe_fds[1]);
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  ::close(pipe_fds[1]);
  stdout_fd_ = pipe_fds[0];

  const std::regex listening(R"(listening on https?://[0-9.]+:([0-9]+)/)");
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::smatch match;
  while (std::chrono::steady_clock::now() < deadline) {
    pollfd p{stdout_fd_, POLLIN, 0};
    if (::poll(&p, 1, 100) > 0) {
      char buffer[4096];
      const ssize_t n = ::read(stdout_fd_, buffer, sizeof buffer);
      if (n <= 0) break;
      output_.append(buffer, static_cast<std::size_t>(n));
      if (std::regex_search(output_, match, listening)) {
        port_ = std::stoi(match[1]);
        break;
      }
    }
  }
  if (port_ == 0) {
    ::kill(pid_, SIGKILL);
    throw std::runtime_error("fesbench-server did not start; output: " + output_);
  }
  std::ifstream token_file(dir_ / "data" / "admin.token");
  std::getline(token_file, admin_token_);
}

ServerProcess::~ServerProcess() {
  if (pid_ > 0) {
    // A server the test left running stops as in production (SIGTERM), so
    // what happens at shutdown is checked too: a crash, a non-zero exit or a
    // sanitizer report at exit (ASan/LSan exit non-zero, UBSan aborts) fails
    // the test.
    const std::string how = Stop(std::chrono::seconds(20));
    if (!how.empty()) {
      ADD_FAILURE() << "fesbench-server " << how << " at shutdown (SIGTERM); stderr:\n"
                    << Stderr();
    }
  }
  if (stdout_fd_ >= 0) ::close(stdout_fd_);
  std::error_code ec;
  if (owns_dir_) std::filesystem::remove_all(dir_, ec);
}

int ServerProcess::Terminate(std::chrono::seconds timeout) {
  if (pid_ <= 0) return -1;
  ::kill(pid_, SIGTERM);
  const std::optional<int> status = WaitExit(timeout);
  if (!status) return -1;
  return WIFEXITED(*status) ? WEXITSTATUS(*status) : -1;
}

std::optional<int> ServerProcess::WaitExit(std::chrono::seconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  int status = 0;
  while (std::chrono::steady_clock::now() < deadline) {
    // Keep draining stdout so the server never blocks on a full pipe.
    char buffer[4096];
    pollfd p{stdout_fd_, POLLIN, 0};
    if (::poll(&p, 1, 20) > 0) {
      const ssize_t n = ::read(stdout_fd_, buffer, sizeof buffer);
      if (n > 0) output_.append(buffer, static_cast<std::size_t>(n));
    }
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      return status;
    }
  }
  return std::nullopt;
}

std::optional<int> ServerProcess::AwaitExit(std::chrono::seconds timeout) {
  if (pid_ <= 0) return std::nullopt;
  const std::optional<int> status = WaitExit(timeout);
  if (!status) return std::nullopt;
  return WIFEXITED(*status) ? WEXITSTATUS(*status) : -1;
}

ExitedServer RunServerToExit(const std::vector<std::string>& args, std::chrono::seconds timeout) {
  const std::filesystem::path dir = NewTempDir();
  const auto out_path = dir / "stdout.log";
  const auto err_path = dir / "stderr.log";
  std::vector<std::string> argv_text = {FESBENCH_SERVER_BINARY};
  argv_text.insert(argv_text.end(), args.begin(), args.end());
  const auto started = std::chrono::steady_clock::now();
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    const int out = ::open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    const int err = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    if (out >= 0) ::dup2(out, STDOUT_FILENO);
    if (err >= 0) ::dup2(err, STDERR_FILENO);
    std::vector<char*> argv;
    for (auto& a : argv_text) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  ExitedServer result;
  int status = 0;
  const auto deadline = started + timeout;
  bool exited = false;
  while (!exited && std::chrono::steady_clock::now() < deadline) {
    if (::waitpid(pid, &status, WNOHANG) == pid) {
      exited = true;
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  }
  result.elapsed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - started).count();
  if (!exited) {
    ::kill(pid, SIGKILL);
    ::waitpid(pid, &status, 0);
  } else if (WIFEXITED(status)) {
    result.exit_code = WEXITSTATUS(status);
  }
  std::ifstream out_file(out_path), err_file(err_path);
  result.output.assign(std::istreambuf_iterator<char>(out_file), {});
  result.error.assign(std::istreambuf_iterator<char>(err_file), {});
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
  return result;
}

std::string ServerProcess::Stop(std::chrono::seconds timeout) {
  ::kill(pid_, SIGTERM);
  const std::optional<int> status = WaitExit(timeout);
  if (!status) {
    Kill();
    return "did not exit within " + std::to_string(timeout.count()) + " s";
  }
  if (WIFSIGNALED(*status)) return "was killed by signal " + std::to_string(WTERMSIG(*status));
  if (WEXITSTATUS(*status) != 0) return "exited with code " + std::to_string(WEXITSTATUS(*status));
  return {};
}

void ServerProcess::Kill() {
  if (pid_ <= 0) return;
  ::kill(pid_, SIGKILL);
  ::waitpid(pid_, nullptr, 0);
  pid_ = -1;
}

httplib::Client ServerProcess::Client() const {
  httplib::Client client("127.0.0.1", port_);
  client.set_connection_timeout(5);
  client.set_read_timeout(10);
  client.set_write_timeout(10);
  return client;
}

JsonResponse Call(httplib::Client& client, const std::string& method, const std::string& path,
                  const std::string& token, const nlohmann::json& body,
                  const std::string& content_type) {
  httplib::Headers headers;
  if (!token.empty()) headers.emplace("Authorization", "Bearer " + token);
  const std::string text = body.is_null() ? std::string() : body.dump();
  httplib::Result result{nullptr, httplib::Error::Unknown};
  if (method == "GET") {
    result = client.Get(path, headers);
  } else if (method == "POST") {
    result = client.Post(path, headers, text, content_type);
  } else if (method == "PUT") {
    result = client.Put(path, headers, text, content_type);
  } else if (method == "DELETE") {
    result = client.Delete(path, headers, text, content_type);
  } else if (method == "PATCH") {
    result = client.Patch(path, headers, text, content_type);
  }
  JsonResponse out;
  if (!result) return out;
  out.status = result->status;
  out.text = result->body;
  out.headers = result->headers;
  out.body = nlohmann::json::parse(result->body, nullptr, false);
  if (out.body.is_discarded()) out.body = nullptr;
  return out;
}

std::string RawExchange(int port, const std::string& request, std::chrono::milliseconds timeout) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd);
    return {};
  }
  std::size_t sent = 0;
  while (sent < request.size()) {
    const ssize_t n = ::send(fd, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) break;
    sent += static_cast<std::size_t>(n);
  }
  std::string response;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 50) <= 0) {
      if (!response.empty() && response.find("\r\n\r\n") != std::string::npos) {
        // A full head arrived and nothing more for a while: enough.
        const auto head_end = response.find("\r\n\r\n");
        const auto length_at = response.find("Content-Length: ");
        if (length_at != std::string::npos && length_at < head_end) {
          const std::size_t length = std::stoul(response.substr(length_at + 16));
          if (response.size() >= head_end + 4 + length) break;
        }
      }
      continue;
    }
    char buffer[8192];
    const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
    if (n <= 0) break;
    response.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(fd);
  return response;
}

std::string ServerProcess::Stderr() const {
  std::ifstream in(dir_ / "stderr.log");
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

int RawStatus(const std::string& response) {
  if (response.rfind("HTTP/1.1 ", 0) != 0 || response.size() < 12) return -1;
  return std::stoi(response.substr(9, 3));
}

std::string CreateUserToken(httplib::Client& client, const std::string& admin_token,
                            const std::string& name, const std::string& role) {
  auto user = Call(client, "POST", "/api/v1/users", admin_token, {{"name", name}, {"role", role}});
  if (user.status != 201) throw std::runtime_error("create user: " + user.text);
  auto token = Call(client, "POST", "/api/v1/tokens", admin_token,
                    {{"user_id", user.body["id"]}, {"label", name}});
  if (token.status != 201) throw std::runtime_error("create token: " + token.text);
  return token.body["token"].get<std::string>();
}

}  // namespace fesbench::testing

namespace fesbench::testing {

RawConnection::RawConnection(int port) {
  fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (fd_ >= 0 && ::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd_);
    fd_ = -1;
  }
}

RawConnection::~RawConnection() {
  if (fd_ >= 0) ::close(fd_);
}

bool RawConnection::Send(const std::string& bytes) {
  std::size_t sent = 0;
  while (fd_ >= 0 && sent < bytes.size()) {
    const ssize_t n = ::send(fd_, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) return false;
    sent += static_cast<std::size_t>(n);
  }
  return fd_ >= 0;
}

void RawConnection::HalfClose() { ::shutdown(fd_, SHUT_WR); }

std::string RawConnection::ReadUntil(const std::function<bool(const std::string&)>& done,
                                     std::chrono::milliseconds timeout) {
  std::string received;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!done(received)) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) break;
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) break;
    char buffer[8192];
    const ssize_t n = ::recv(fd_, buffer, sizeof buffer, 0);
    if (n <= 0) break;
    received.append(buffer, static_cast<std::size_t>(n));
  }
  return received;
}

bool RawConnection::ClosedByPeer() {
  pollfd p{fd_, POLLIN, 0};
  if (::poll(&p, 1, 0) <= 0) return false;
  char byte;
  const ssize_t n = ::recv(fd_, &byte, 1, MSG_PEEK | MSG_DONTWAIT);
  return n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK);
}

int CountResponses(const std::string& bytes) {
  int count = 0;
  std::size_t pos = 0;
  while (pos < bytes.size()) {
    const std::size_t head_end = bytes.find("\r\n\r\n", pos);
    if (head_end == std::string::npos || bytes.compare(pos, 5, "HTTP/") != 0) break;
    const std::string head = bytes.substr(pos, head_end - pos);
    std::size_t length = 0;
    const std::size_t at = head.find("Content-Length: ");
    if (at != std::string::npos) length = std::stoul(head.substr(at + 16));
    if (bytes.size() < head_end + 4 + length) break;
    ++count;
    pos = head_end + 4 + length;
  }
  return count;
}

nlohmann::json WaitForJob(httplib::Client& client, const std::string& token, std::int64_t id) {
  for (int i = 0; i < 1200; ++i) {
    auto job = Call(client, "GET", "/api/v1/jobs/" + std::to_string(id), token);
    if (job.status != 200) return job.body;
    const std::string state = job.body["state"];
    if (state == "done" || state == "failed") return job.body;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return nullptr;
}

nlohmann::json RunToEnd(httplib::Client& client, const std::string& token,
                        std::int64_t session_id, const nlohmann::json& request) {
  auto run = Call(client, "POST", "/api/v1/sessions/" + std::to_string(session_id) + "/runs",
                  token, request);
  EXPECT_EQ(run.status, 201) << run.text;
  const std::string path = "/api/v1/runs/" + std::to_string(run.body["run_id"].get<int>());
  for (int i = 0; i < 1200; ++i) {
    Call(client, "POST", path + "/heartbeat", token);
    auto view = Call(client, "GET", path, token);
    const std::string state = view.body.value("state", "");
    if (state == "done" || state == "aborted" || state == "failed") return view.body;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ADD_FAILURE() << "run did not end";
  return nullptr;
}

}  // namespace fesbench::testing
