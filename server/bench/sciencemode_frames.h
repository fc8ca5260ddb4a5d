#pragma once

/// @file
/// The frames a ScienceMode stimulator sends, read from its serial port.
/// ScienceMode2 (description v1.24 §2.2) and ScienceMode4 use the same
/// start and stop bytes and the same byte stuffing, so both drivers read
/// through one FrameReader; decoding a frame stays with each protocol.
///
/// Not thread-safe: a driver reads under its own I/O lock.

#include <chrono>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include "api/status.h"
#include "server/bench/sciencemode2_packet.h"
#include "server/bench/serial_port.h"

namespace fesbench::server {

/// What the bench reports when the port goes away under a driver.
inline constexpr char kStimulatorLost[] =
    "stimulator lost: the serial port hung up (cable pulled or device off)";

class FrameReader {
 public:
  using Frame = std::vector<std::uint8_t>;
  enum class ReadOutcome {
    kRead,      ///< the port answered (possibly with no whole frame yet).
    kTimedOut,  ///< the deadline passed with nothing read.
    kHungUp,    ///< the port is gone (hang-up, EOF or error).
  };

  /// `port` outlives the reader.
  explicit FrameReader(SerialPort& port) : port_(port) {}

  /// The oldest whole frame read so far; nullopt when none is buffered.
  std::optional<Frame> Pop();

  /// One read of what arrives before `deadline` (kTimedOut at once if it has
  /// passed), split into frames.
  ReadOutcome ReadBefore(std::chrono::steady_clock::time_point deadline);

  /// ReadBefore for a reply due within `reply_timeout` of the request: OK
  /// once the port answered, else kUnavailable with the fault the driver
  /// reports ("stimulator timeout: no reply within 150 ms", kStimulatorLost).
  api::Status ReadReply(std::chrono::steady_clock::time_point deadline,
                        std::chrono::milliseconds reply_timeout);

  /// One read of what the port already holds, without waiting: kRead or
  /// kHungUp.
  ReadOutcome ReadAvailable();

 private:
  ReadOutcome ReadFor(std::chrono::milliseconds timeout);

  SerialPort& port_;
  sciencemode2::FrameSplitter splitter_;
  std::deque<Frame> frames_;
};

}  // namespace fesbench::server
