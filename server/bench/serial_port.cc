#include "server/bench/serial_port.h"

#include <dirent.h>
#include <fcntl.h>
#include <poll.h>
#include <sys/file.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <utility>

namespace fesbench::server {
namespace {

struct Speed {
  int baud;
  speed_t code;
};
constexpr Speed kSpeeds[] = {{9600, B9600},       {19200, B19200},     {38400, B38400},
                             {57600, B57600},     {115200, B115200},   {230400, B230400},
                             {460800, B460800},   {921600, B921600},   {1000000, B1000000},
                             {2000000, B2000000}, {3000000, B3000000}};

speed_t SpeedCode(int baud) {
  for (const Speed& s : kSpeeds) {
    if (s.baud == baud) return s.code;
  }
  return B0;
}

int BaudOf(speed_t code) {
  for (const Speed& s : kSpeeds) {
    if (s.code == code) return s.baud;
  }
  return 0;
}

// The process (other than this one) with `path`'s device open, as
// "process 1234 (fesbench-server)", or "another process" when /proc does
// not tell (another user's processes are not readable without privilege).
std::string Holder(const std::string& path) {
  struct stat device {};
  if (::stat(path.c_str(), &device) != 0) return "another process";
  DIR* proc = ::opendir("/proc");
  if (proc == nullptr) return "another process";
  std::string found = "another process";
  const std::string self = std::to_string(::getpid());
  while (dirent* entry = ::readdir(proc)) {
    const std::string pid = entry->d_name;
    if (pid.empty() || pid.find_first_not_of("0123456789") != std::string::npos || pid == self) {
      continue;
    }
    const std::string fds = "/proc/" + pid + "/fd";
    DIR* dir = ::opendir(fds.c_str());
    if (dir == nullptr) continue;
    bool holds = false;
    while (dirent* fd = ::readdir(dir)) {
      struct stat open {};
      if (fd->d_name[0] == '.') continue;
      if (::stat((fds + "/" + fd->d_name).c_str(), &open) == 0 && S_ISCHR(open.st_mode) &&
          open.st_rdev == device.st_rdev) {
        holds = true;
        break;
      }
    }
    ::closedir(dir);
    if (holds) {
      std::string name;
      std::ifstream comm("/proc/" + pid + "/comm");
      std::getline(comm, name);
      found = "process " + pid + (name.empty() ? "" : " (" + name + ")");
      break;
    }
  }
  ::closedir(proc);
  return found;
}

// A pseudo-terminal's slave side (UNIX98: majors 136–143). Linux's pty
// driver keeps no parity (pty_set_termios clears PARENB and forces CS8), so
// parity is not read back there.
bool IsPseudoTerminal(int fd) {
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISCHR(st.st_mode)) return false;
  const unsigned int m = major(st.st_rdev);
  return m >= 136 && m <= 143;
}

}  // namespace

std::string SerialSettings::Describe() const {
  return std::to_string(baud) + " 8" + (even_parity ? "E" : "N") + std::to_string(stop_bits) +
         (rts_cts ? ", RTS/CTS" : ", no flow control");
}

SerialSettings ScienceMode2Settings() { return {460800, true, 1, false}; }

SerialSettings ScienceMode4Settings() { return {3000000, false, 2, true}; }

SerialSettings ReadSettings(int fd) {
  SerialSettings s;
  termios tio{};
  if (::tcgetattr(fd, &tio) != 0) return s;
  s.baud = BaudOf(::cfgetospeed(&tio)) == BaudOf(::cfgetispeed(&tio)) ? BaudOf(::cfgetospeed(&tio))
                                                                      : 0;
  s.even_parity = (tio.c_cflag & PARENB) != 0 && (tio.c_cflag & PARODD) == 0;
  s.stop_bits = (tio.c_cflag & CSTOPB) != 0 ? 2 : 1;
  s.rts_cts = (tio.c_cflag & CRTSCTS) != 0;
  if ((tio.c_cflag & CSIZE) != CS8 || ((tio.c_cflag & PARODD) != 0)) s.baud = 0;  // not 8 bits / odd
  return s;
}

SerialPort::SerialPort(SerialPort&& other) noexcept : fd_(std::exchange(other.fd_, -1)) {}

SerialPort& SerialPort::operator=(SerialPort&& other) noexcept {
  if (this != &other) {
    Close();
    fd_ = std::exchange(other.fd_, -1);
  }
  return *this;
}

SerialPort::~SerialPort() { Close(); }

SerialSettings SerialPort::settings() const {
  if (fd_ < 0) return {0, false, 0, false};
  return ReadSettings(fd_);
}

void SerialPort::Close() {
  if (fd_ >= 0) {
    ::ioctl(fd_, TIOCNXCL);
    ::close(fd_);  // also releases the flock
  }
  fd_ = -1;
}

api::Status SerialPort::Open(const std::string& path, const SerialSettings& settings) {
  Close();
  const std::string where = "serial port " + path;
  const speed_t speed = SpeedCode(settings.baud);
  if (speed == B0) {
    return api::Status::InvalidArgument(where + ": unsupported baud rate " +
                                        std::to_string(settings.baud));
  }
  if (settings.stop_bits != 1 && settings.stop_bits != 2) {
    return api::Status::InvalidArgument(where + ": stop bits must be 1 or 2, got " +
                                        std::to_string(settings.stop_bits));
  }
  // O_NONBLOCK: the open does not wait for a carrier a port's last user may
  // have left it expecting (CLOCAL off); cleared once the port is set.
  const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) {
    return api::Status::Unavailable(
        where + ": " + std::strerror(errno) +
        (errno == EBUSY ? " (held exclusively by " + Holder(path) + ")" : ""));
  }
  auto fail = [&](const std::string& why) {
    ::close(fd);
    return api::Status::Unavailable(where + ": " + why);
  };
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    return fail(errno == EWOULDBLOCK ? "in use by " + Holder(path) + " (one stimulator, one server)"
                                     : std::string("cannot lock (") + std::strerror(errno) + ")");
  }
  termios tio{};
  if (::tcgetattr(fd, &tio) != 0) return fail(std::string("not a terminal (") + std::strerror(errno) + ")");
  ::ioctl(fd, TIOCEXCL);
  // Every flag from zero: nothing a previous program set (another speed
  // encoding, canonical mode, echo, software flow control) survives.
  tio = termios{};
  tio.c_cflag = CS8 | CLOCAL | CREAD;
  if (settings.even_parity) tio.c_cflag |= PARENB;
  if (settings.stop_bits == 2) tio.c_cflag |= CSTOPB;
  if (settings.rts_cts) tio.c_cflag |= CRTSCTS;
  tio.c_iflag = IGNBRK | (settings.even_parity ? 0 : IGNPAR);
  tio.c_cc[VMIN] = 0;  // reads are bounded by poll(), not by the driver
  tio.c_cc[VTIME] = 0;
  if (::cfsetispeed(&tio, speed) != 0 || ::cfsetospeed(&tio, speed) != 0 ||
      ::tcsetattr(fd, TCSANOW, &tio) != 0) {
    return fail("cannot configure " + settings.Describe() + " (" + std::strerror(errno) + ")");
  }
  const SerialSettings kept = ReadSettings(fd);
  const bool parity_kept = kept.even_parity == settings.even_parity || IsPseudoTerminal(fd);
  if (kept.baud != settings.baud || !parity_kept ||
      kept.stop_bits != settings.stop_bits || kept.rts_cts != settings.rts_cts) {
    return fail("set to " + settings.Describe() + " but reads back " +
                (kept.baud == 0 ? std::string("another speed or character size")
                                : kept.Describe()));
  }
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  ::tcflush(fd, TCIOFLUSH);
  fd_ = fd;
  return api::Status::Ok();
}

api::Status SerialPort::Write(std::span<const std::uint8_t> bytes) {
  if (fd_ < 0) return api::Status::Unavailable("serial port not open");
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      return api::Status::Unavailable(std::string("serial write failed: ") + std::strerror(errno));
    }
    done += static_cast<std::size_t>(n);
  }
  return api::Status::Ok();
}

int SerialPort::Read(std::span<std::uint8_t> buffer, std::chrono::milliseconds timeout) {
  if (fd_ < 0) return -1;
  pollfd p{fd_, POLLIN, 0};
  int r;
  do {
    r = ::poll(&p, 1, static_cast<int>(timeout.count()));
  } while (r < 0 && errno == EINTR);
  if (r < 0) return -1;
  if (r == 0) return 0;
  if (p.revents & POLLIN) {
    const ssize_t n = ::read(fd_, buffer.data(), buffer.size());
    if (n > 0) return static_cast<int>(n);
    if (n < 0 && (errno == EAGAIN || errno == EINTR)) return 0;
    return -1;  // EOF or EIO: the other end is gone
  }
  return -1;  // POLLHUP / POLLERR without data
}

}  // namespace fesbench::server
