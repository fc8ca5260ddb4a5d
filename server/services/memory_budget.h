#pragma once

/// @file
/// One byte budget that every upload being imported draws its memory from
/// (docs/SAFETY.md "Uploads"): an archive's unpacked entries, a recording's
/// text and what parsing it holds. Whatever the number of concurrent
/// uploads, the server holds at most the budget's capacity for them; a
/// request that finds the budget spent is refused (kUnavailable, 503 with
/// Retry-After) instead of waiting or growing.

#include <cstddef>
#include <mutex>

#include "api/status.h"

namespace fesbench::server::services {

class MemoryBudget {
 public:
  /// `capacity_bytes`: the most all reservations together may hold.
  explicit MemoryBudget(std::size_t capacity_bytes);
  MemoryBudget(const MemoryBudget&) = delete;
  MemoryBudget& operator=(const MemoryBudget&) = delete;

  /// Bytes drawn from a budget, given back when it is destroyed (or
  /// resized down). Movable; a default-constructed one holds nothing.
  class Reservation {
   public:
    Reservation() = default;
    ~Reservation();
    Reservation(Reservation&& other) noexcept;
    Reservation& operator=(Reservation&& other) noexcept;
    Reservation(const Reservation&) = delete;
    Reservation& operator=(const Reservation&) = delete;

    /// Holds `bytes` from now on. Shrinking always succeeds; growing is
    /// kUnavailable when the budget has not that much left (the
    /// reservation then keeps what it held).
    api::Status Resize(std::size_t bytes);
    std::size_t bytes() const { return bytes_; }

   private:
    friend class MemoryBudget;
    explicit Reservation(MemoryBudget* budget) : budget_(budget) {}
    MemoryBudget* budget_ = nullptr;
    std::size_t bytes_ = 0;
  };

  /// A reservation of `bytes`; kUnavailable "the server is busy with other
  /// uploads; retry" when the budget has not that much left.
  api::Result<Reservation> Reserve(std::size_t bytes);

  std::size_t capacity() const { return capacity_; }
  /// Bytes held by all reservations now.
  std::size_t in_use() const;

 private:
  api::Status Take(std::size_t bytes);
  void Give(std::size_t bytes);

  const std::size_t capacity_;
  mutable std::mutex mutex_;
  std::size_t in_use_ = 0;
};

}  // namespace fesbench::server::services
