#pragma once

/// @file
/// A serial port through termios, raw, opened with the settings of the
/// device behind it (SerialSettings: baud rate, parity, stop bits, RTS/CTS)
/// and checked back with tcgetattr after they are set. The port is held
/// exclusively while open: an advisory lock (flock) that a second
/// fesbench-server, or any program that takes the same lock, is refused by
/// naming the process that holds it, and TIOCEXCL against plain opens by
/// others (root is exempt from the latter). On a pseudo-terminal (the
/// emulator's) parity is not checked back: Linux's pty driver keeps none.
/// Whatever settings another
/// program left on the port are replaced whole, not edited. Reads take a
/// timeout.

#include <chrono>
#include <cstdint>
#include <span>
#include <string>

#include "api/status.h"

namespace fesbench::server {

/// A device's line settings, 8 data bits always.
struct SerialSettings {
  int baud = 0;
  bool even_parity = false;  ///< else no parity.
  int stop_bits = 1;         ///< 1 or 2.
  bool rts_cts = false;      ///< hardware flow control.
  /// "460800 8E1, no flow control", for messages and the server's log.
  std::string Describe() const;
};

/// The RehaStim 2 (ScienceMode2 description v1.24 §2.1 Table 4): 460 800
/// baud, 8 data bits, even parity, 1 stop bit, no flow control.
SerialSettings ScienceMode2Settings();
/// The P24 (the public ScienceMode4 C library, smpt_serial_port.c
/// smpt_open_serial_port_internal for Linux: B3000000, and
/// smpt_serial_port_linux.c smpt_open_serial_port_linux: CS8 | CLOCAL |
/// CREAD | CRTSCTS | CSTOPB, parity cleared): 3 000 000 baud, 8N2, RTS/CTS.
SerialSettings ScienceMode4Settings();

class SerialPort {
 public:
  SerialPort() = default;
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;
  SerialPort(SerialPort&& other) noexcept;
  SerialPort& operator=(SerialPort&& other) noexcept;
  ~SerialPort();

  /// Opens `path`, takes it exclusively, sets `settings` and reads them
  /// back. OK on success, else a Status whose message is a sentence naming
  /// the path and the reason: kInvalidArgument for settings no port can
  /// have (baud rate, stop bits), kUnavailable for the rest (errno text,
  /// the process holding the port, or the setting the port did not keep).
  api::Status Open(const std::string& path, const SerialSettings& settings);
  bool is_open() const { return fd_ >= 0; }
  void Close();
  /// The settings the terminal has now (ReadSettings); all zero if closed.
  SerialSettings settings() const;

  /// Writes all bytes. OK, or kUnavailable naming the reason it could not.
  api::Status Write(std::span<const std::uint8_t> bytes);

  /// Reads what is available, waiting at most `timeout`. Returns the count
  /// read (0 on timeout), or −1 if the port is gone (hang-up, EOF or error).
  int Read(std::span<std::uint8_t> buffer, std::chrono::milliseconds timeout);

 private:
  int fd_ = -1;
};

/// The settings a terminal has now (tcgetattr on an open descriptor), as
/// far as SerialSettings describes them; baud 0 for a speed it does not
/// know. For the checks after Open and for tests.
SerialSettings ReadSettings(int fd);

}  // namespace fesbench::server
