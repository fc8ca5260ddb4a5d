// fesbench-server under systemd's Type=notify (README, "Install on a lab
// PC"): it sends READY=1 to NOTIFY_SOCKET only once its HTTP port answers,
// and STOPPING=1 at SIGTERM before it exits 0. The test plays systemd: a
// unix datagram socket of its own as NOTIFY_SOCKET, a port chosen free
// beforehand, and a connection to that port the moment READY=1 arrives.

#include <arpa/inet.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <vector>

#ifndef FESBENCH_SERVER_BINARY
#error "FESBENCH_SERVER_BINARY must name the fesbench-server executable"
#endif

namespace {

namespace fs = std::filesystem;

// A loopback port nothing listens on right now.
int FreePort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address);
  socklen_t size = sizeof address;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &size);
  ::close(fd);
  return ntohs(address.sin_port);
}

// The whole answer to `GET path` on 127.0.0.1:port, or nullopt when the
// connection is refused.
std::optional<std::string> Get(int port, const std::string& path) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    ::close(fd);
    return std::nullopt;
  }
  const std::string request = "GET " + path + " HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n";
  (void)!::write(fd, request.data(), request.size());
  std::string answer;
  char buffer[4096];
  for (ssize_t n; (n = ::read(fd, buffer, sizeof buffer)) > 0;) answer.append(buffer, n);
  ::close(fd);
  return answer;
}

// The next datagram on `fd` within `timeout`, or "" on timeout.
std::string Receive(int fd, std::chrono::milliseconds timeout) {
  pollfd p{fd, POLLIN, 0};
  if (::poll(&p, 1, static_cast<int>(timeout.count())) != 1) return {};
  char buffer[4096];
  const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
  return n > 0 ? std::string(buffer, static_cast<std::size_t>(n)) : std::string();
}

class ServiceReadinessTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char pattern[] = "/tmp/fesbench-notify-XXXXXX";
    ASSERT_NE(::mkdtemp(pattern), nullptr);
    dir_ = pattern;
    notify_fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un address{};
    address.sun_family = AF_UNIX;
    socket_path_ = (dir_ / "notify").string();
    std::snprintf(address.sun_path, sizeof address.sun_path, "%s", socket_path_.c_str());
    ASSERT_EQ(::bind(notify_fd_, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
  }
  void TearDown() override {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
    ::close(notify_fd_);
    fs::remove_all(dir_);
  }

  // Starts the server on `port` with NOTIFY_SOCKET set (only in the child);
  // with `journal`, JOURNAL_STREAM names its output as systemd does when the
  // output is the journal's stream.
  void Start(int port, bool journal = false) {
    const std::string port_text = std::to_string(port);
    const std::string db = (dir_ / "data" / "fesbench.db").string();
    const std::string log = (dir_ / "server.log").string();
    pid_ = ::fork();
    if (pid_ == 0) {
      ::setenv("NOTIFY_SOCKET", socket_path_.c_str(), 1);
      const int out = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
      ::dup2(out, STDOUT_FILENO);
      ::dup2(out, STDERR_FILENO);
      struct stat info {};
      if (journal && ::fstat(STDOUT_FILENO, &info) == 0) {
        const std::string stream = std::to_string(info.st_dev) + ":" + std::to_string(info.st_ino);
        ::setenv("JOURNAL_STREAM", stream.c_str(), 1);
      }
      std::vector<const char*> argv = {FESBENCH_SERVER_BINARY, "--port", port_text.c_str(),
                                       "--db", db.c_str(), "--time-scale", "0",
                                       "--dds-transport", "off", nullptr};
      ::execv(argv[0], const_cast<char* const*>(argv.data()));
      ::_exit(127);
    }
  }

  fs::path dir_;
  std::string socket_path_;
  int notify_fd_ = -1;
  pid_t pid_ = -1;
};

TEST_F(ServiceReadinessTest, ReadyOnlyOnceThePortAnswersAndStoppingAtSigterm) {
  const int port = FreePort();
  Start(port);
  // Nothing but READY=1 may come first; the port must answer the moment it does.
  const std::string ready = Receive(notify_fd_, std::chrono::seconds(30));
  ASSERT_NE(ready.find("READY=1"), std::string::npos) << "first notification: '" << ready << "'";
  const std::optional<std::string> health = Get(port, "/api/v1/health");
  ASSERT_TRUE(health.has_value()) << "READY=1 came before the port answered";
  EXPECT_NE(health->find("200 OK"), std::string::npos) << *health;
  EXPECT_NE(ready.find("STATUS=listening on port " + std::to_string(port)), std::string::npos)
      << ready;

  ASSERT_EQ(::kill(pid_, SIGTERM), 0);
  const std::string stopping = Receive(notify_fd_, std::chrono::seconds(20));
  EXPECT_NE(stopping.find("STOPPING=1"), std::string::npos) << "'" << stopping << "'";
  int status = 0;
  ASSERT_EQ(::waitpid(pid_, &status, 0), pid_);
  pid_ = -1;
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
}

TEST_F(ServiceReadinessTest, NoNotificationWhenTheServerCannotListen) {
  // A port already taken: the server exits 1 without ever saying READY=1.
  const int blocker = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(blocker, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
  ASSERT_EQ(::listen(blocker, 1), 0);
  socklen_t size = sizeof address;
  ::getsockname(blocker, reinterpret_cast<sockaddr*>(&address), &size);
  Start(ntohs(address.sin_port));
  int status = 0;
  ASSERT_EQ(::waitpid(pid_, &status, 0), pid_);
  pid_ = -1;
  ::close(blocker);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1);
  EXPECT_EQ(Receive(notify_fd_, std::chrono::milliseconds(100)), "");
}

// Under the service the output is the journal, kept and readable by others
// than the server's user (group adm): the first admin's token is only in
// admin.token there, the journal names the file.
TEST_F(ServiceReadinessTest, TheFirstAdminTokenIsNotPrintedToTheJournal) {
  const int port = FreePort();
  Start(port, /*journal=*/true);
  ASSERT_NE(Receive(notify_fd_, std::chrono::seconds(30)).find("READY=1"), std::string::npos);
  std::ifstream token_file(dir_ / "data" / "admin.token");
  std::string token;
  ASSERT_TRUE(std::getline(token_file, token));
  EXPECT_TRUE(token.starts_with("fsb_")) << token;
  std::ifstream log_file(dir_ / "server.log");
  const std::string log((std::istreambuf_iterator<char>(log_file)),
                        std::istreambuf_iterator<char>());
  EXPECT_EQ(log.find(token), std::string::npos) << log;
  EXPECT_NE(log.find("its token is in " + (dir_ / "data" / "admin.token").string() +
                     " (not printed: this output goes to the journal)"),
            std::string::npos)
      << log;
}

}  // namespace
