#pragma once

/// @file
/// A serial port through termios: raw mode, 8 data bits, even parity, 1 stop
/// bit, no flow control, at a given baud rate (ScienceMode2 description
/// v1.24 §2.1 Table 4: 460 800 baud, 8E1, no RTS/CTS). Reads take a timeout.

#include <chrono>
#include <cstdint>
#include <span>
#include <string>

namespace fesbench::server {

class SerialPort {
 public:
  SerialPort() = default;
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;
  SerialPort(SerialPort&& other) noexcept;
  SerialPort& operator=(SerialPort&& other) noexcept;
  ~SerialPort();

  /// Opens `path` and configures it. Returns "" on success, else a sentence
  /// naming the path and the reason (errno text).
  std::string Open(const std::string& path, int baud = 460800);
  bool is_open() const { return fd_ >= 0; }
  void Close();

  /// Writes all bytes. Returns "" or the reason it could not.
  std::string Write(std::span<const std::uint8_t> bytes);

  /// Reads what is available, waiting at most `timeout`. Returns the count
  /// read (0 on timeout), or −1 if the port is gone (hang-up, EOF or error).
  int Read(std::span<std::uint8_t> buffer, std::chrono::milliseconds timeout);

 private:
  int fd_ = -1;
};

}  // namespace fesbench::server
