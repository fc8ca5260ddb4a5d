#include "server/bench/sciencemode_frames.h"

#include <span>
#include <utility>

namespace fesbench::server {

std::optional<FrameReader::Frame> FrameReader::Pop() {
  if (frames_.empty()) return std::nullopt;
  Frame frame = std::move(frames_.front());
  frames_.pop_front();
  return frame;
}

FrameReader::ReadOutcome FrameReader::ReadBefore(std::chrono::steady_clock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
      deadline - std::chrono::steady_clock::now());
  if (left.count() <= 0) return ReadOutcome::kTimedOut;
  return ReadFor(left);
}

api::Status FrameReader::ReadReply(std::chrono::steady_clock::time_point deadline,
                                   std::chrono::milliseconds reply_timeout) {
  switch (ReadBefore(deadline)) {
    case ReadOutcome::kRead:
      return api::Status::Ok();
    case ReadOutcome::kTimedOut:
      return api::Status::Unavailable("stimulator timeout: no reply within " +
                                      std::to_string(reply_timeout.count()) + " ms");
    case ReadOutcome::kHungUp:
      return api::Status::Unavailable(kStimulatorLost);
  }
  return api::Status::Unavailable(kStimulatorLost);
}

FrameReader::ReadOutcome FrameReader::ReadAvailable() {
  return ReadFor(std::chrono::milliseconds(0));
}

FrameReader::ReadOutcome FrameReader::ReadFor(std::chrono::milliseconds timeout) {
  std::uint8_t buffer[512];
  const int n = port_.Read(buffer, timeout);
  if (n < 0) return ReadOutcome::kHungUp;
  for (auto& frame : splitter_.Feed(std::span(buffer, static_cast<std::size_t>(n)))) {
    frames_.push_back(std::move(frame));
  }
  return ReadOutcome::kRead;
}

}  // namespace fesbench::server
