#include "server/services/memory_budget.h"

#include <cassert>
#include <string>
#include <utility>

namespace fesbench::server::services {

MemoryBudget::MemoryBudget(std::size_t capacity_bytes) : capacity_(capacity_bytes) {}

std::size_t MemoryBudget::in_use() const {
  std::lock_guard lock(mutex_);
  return in_use_;
}

api::Status MemoryBudget::Take(std::size_t bytes) {
  std::lock_guard lock(mutex_);
  if (bytes > capacity_ - in_use_) {
    return api::Status::Unavailable(
        "the server is busy with other uploads (" + std::to_string(in_use_ >> 20) + " of its " +
        std::to_string(capacity_ >> 20) + " MiB for imports in use); retry");
  }
  in_use_ += bytes;
  return api::Status::Ok();
}

void MemoryBudget::Give(std::size_t bytes) {
  std::lock_guard lock(mutex_);
  in_use_ -= bytes;
}

api::Result<MemoryBudget::Reservation> MemoryBudget::Reserve(std::size_t bytes) {
  Reservation reservation(this);
  if (api::Status s = reservation.Resize(bytes); !s.ok()) return s;
  return reservation;
}

MemoryBudget::Reservation::~Reservation() {
  if (budget_ != nullptr) budget_->Give(bytes_);
}

MemoryBudget::Reservation::Reservation(Reservation&& other) noexcept
    : budget_(std::exchange(other.budget_, nullptr)), bytes_(std::exchange(other.bytes_, 0)) {}

MemoryBudget::Reservation& MemoryBudget::Reservation::operator=(Reservation&& other) noexcept {
  if (this != &other) {
    if (budget_ != nullptr) budget_->Give(bytes_);
    budget_ = std::exchange(other.budget_, nullptr);
    bytes_ = std::exchange(other.bytes_, 0);
  }
  return *this;
}

api::Status MemoryBudget::Reservation::Resize(std::size_t bytes) {
  assert((budget_ != nullptr || bytes == 0) && "a default reservation holds nothing");
  if (budget_ == nullptr) return api::Status::Ok();
  if (bytes <= bytes_) {
    budget_->Give(bytes_ - bytes);
  } else if (api::Status s = budget_->Take(bytes - bytes_); !s.ok()) {
    return s;
  }
  bytes_ = bytes;
  return api::Status::Ok();
}

}  // namespace fesbench::server::services
