#pragma once

/// @file
/// Bounds the number of open event streams (each holds one worker thread
/// for its whole life, http_server.h) and tells them when the server stops.

#include <atomic>
#include <cstddef>
#include <memory>

namespace fesbench::server::http {

class StreamSlots {
 public:
  explicit StreamSlots(std::size_t capacity) : capacity_(capacity) {}

  /// A held slot; releases it when destroyed.
  class Slot {
   public:
    explicit Slot(StreamSlots* owner) : owner_(owner) {}
    ~Slot() { owner_->open_.fetch_sub(1); }
    Slot(const Slot&) = delete;
    Slot& operator=(const Slot&) = delete;

   private:
    StreamSlots* owner_;
  };

  /// A slot, or nullptr when `capacity` streams are open or the server is
  /// shutting down.
  std::unique_ptr<Slot> TryAcquire() {
    if (shutting_down()) return nullptr;
    std::size_t open = open_.load();
    do {
      if (open >= capacity_) return nullptr;
    } while (!open_.compare_exchange_weak(open, open + 1));
    return std::make_unique<Slot>(this);
  }
  /// Streams see shutting_down() and end at their next poll.
  void Shutdown() { shutting_down_.store(true); }
  bool shutting_down() const { return shutting_down_.load(); }
  std::size_t open() const { return open_.load(); }
  std::size_t capacity() const { return capacity_; }

 private:
  std::size_t capacity_;
  std::atomic<std::size_t> open_{0};
  std::atomic<bool> shutting_down_{false};
};

}  // namespace fesbench::server::http
