#include "server/bench/serial_port.h"

#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <utility>

namespace fesbench::server {
namespace {

speed_t BaudConstant(int baud) {
  switch (baud) {
    case 9600:
      return B9600;
    case 19200:
      return B19200;
    case 38400:
      return B38400;
    case 57600:
      return B57600;
    case 115200:
      return B115200;
    case 230400:
      return B230400;
    case 460800:
      return B460800;
    case 921600:
      return B921600;
    default:
      return B0;
  }
}

}  // namespace

SerialPort::SerialPort(SerialPort&& other) noexcept : fd_(std::exchange(other.fd_, -1)) {}

SerialPort& SerialPort::operator=(SerialPort&& other) noexcept {
  if (this != &other) {
    Close();
    fd_ = std::exchange(other.fd_, -1);
  }
  return *this;
}

SerialPort::~SerialPort() { Close(); }

void SerialPort::Close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

std::string SerialPort::Open(const std::string& path, int baud) {
  Close();
  const speed_t speed = BaudConstant(baud);
  if (speed == B0) return "serial port " + path + ": unsupported baud rate " + std::to_string(baud);
  const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
  if (fd < 0) return "serial port " + path + ": " + std::strerror(errno);
  termios tio{};
  if (::tcgetattr(fd, &tio) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    return "serial port " + path + ": not a terminal (" + why + ")";
  }
  ::cfmakeraw(&tio);
  tio.c_cflag |= CLOCAL | CREAD | PARENB;  // Table 4: even parity
  tio.c_cflag &= ~(PARODD | CSTOPB | CRTSCTS | CSIZE);
  tio.c_cflag |= CS8;
  tio.c_cc[VMIN] = 0;  // reads are bounded by poll(), not by the driver
  tio.c_cc[VTIME] = 0;
  ::cfsetispeed(&tio, speed);
  ::cfsetospeed(&tio, speed);
  if (::tcsetattr(fd, TCSANOW, &tio) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    return "serial port " + path + ": cannot configure (" + why + ")";
  }
  ::tcflush(fd, TCIOFLUSH);
  fd_ = fd;
  return "";
}

std::string SerialPort::Write(std::span<const std::uint8_t> bytes) {
  if (fd_ < 0) return "serial port not open";
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      return std::string("serial write failed: ") + std::strerror(errno);
    }
    done += static_cast<std::size_t>(n);
  }
  return "";
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
