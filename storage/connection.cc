#include "storage/connection.h"

#include <bit>
#include <cstring>

namespace fesbench::storage {

// ---------------------------------------------------------------- Statement

Statement::Statement(Statement&& other) noexcept : impl_(other.impl_), owned_(other.owned_) {
  other.impl_ = nullptr;
}

Statement::~Statement() {
  if (impl_ == nullptr) return;
  if (owned_) {
    delete impl_;
  } else {
    impl_->Release();
  }
}

api::Status Statement::Run() {
  while (true) {
    auto row = Step();
    if (!row.ok()) return row.status();
    if (!*row) return api::Status::Ok();
  }
}

std::optional<std::int64_t> Statement::OptionalInt64(int column) const {
  if (IsNull(column)) return std::nullopt;
  return Int64(column);
}

std::optional<double> Statement::OptionalDouble(int column) const {
  if (IsNull(column)) return std::nullopt;
  return Double(column);
}

// --------------------------------------------------------------- Connection

api::Result<std::string> Connection::QueryText(const std::string& sql) {
  auto statement = Prepare(sql);
  if (!statement.ok()) return statement.status();
  auto row = statement->Step();
  if (!row.ok()) return row.status();
  if (!*row) return std::string();
  return statement->Text(0);
}

// ------------------------------------------------------------------ samples

std::vector<std::byte> PackFloat64Le(std::span<const double> samples) {
  std::vector<std::byte> blob(samples.size() * sizeof(double));
  if constexpr (std::endian::native == std::endian::little) {
    if (!samples.empty()) std::memcpy(blob.data(), samples.data(), blob.size());
  } else {
    for (std::size_t i = 0; i < samples.size(); ++i) {
      const auto bits = std::bit_cast<std::uint64_t>(samples[i]);
      for (int b = 0; b < 8; ++b) {
        blob[i * 8 + static_cast<std::size_t>(b)] =
            static_cast<std::byte>((bits >> (8 * b)) & 0xff);
      }
    }
  }
  return blob;
}

std::optional<std::vector<double>> UnpackFloat64Le(std::span<const std::byte> blob) {
  if (blob.size() % sizeof(double) != 0) return std::nullopt;
  std::vector<double> samples(blob.size() / sizeof(double));
  if constexpr (std::endian::native == std::endian::little) {
    if (!blob.empty()) std::memcpy(samples.data(), blob.data(), blob.size());
  } else {
    for (std::size_t i = 0; i < samples.size(); ++i) {
      std::uint64_t bits = 0;
      for (int b = 0; b < 8; ++b) {
        bits |= static_cast<std::uint64_t>(blob[i * 8 + static_cast<std::size_t>(b)]) << (8 * b);
      }
      samples[i] = std::bit_cast<double>(bits);
    }
  }
  return samples;
}

}  // namespace fesbench::storage
