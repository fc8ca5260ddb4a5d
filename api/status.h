#pragma once

/// @file
/// Expected run-time failures as values (docs/API.md, "HTTP conventions"): a Status names
/// what went wrong, with a machine-readable code, a human message and, for
/// bad input, the offending field. Each boundary translates it exactly once
/// (e.g. to an HTTP status and `{"error": {...}}` in the server).

#include <cassert>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

namespace fesbench::api {

enum class ErrorCode {
  kOk,
  kInvalidArgument,     ///< malformed or out-of-range input (HTTP 400/422).
  kNotFound,            ///< unknown id or route (404).
  kAlreadyExists,       ///< duplicate unique key (409).
  kConflict,            ///< state conflict: bench busy, e-stop latched (409).
  kFailedPrecondition,  ///< refused by a rule, e.g. a safety interlock (409/422).
  kUnauthenticated,     ///< missing or invalid token (401).
  kPermissionDenied,    ///< wrong role (403).
  kUnavailable,         ///< busy database or bench fault; retry may succeed (503).
  kPayloadTooLarge,     ///< input beyond a size limit, however often sent (413).
  kDataLoss,            ///< corrupt stored data.
  kInternal,            ///< a bug; never caused by client input.
};

/// The wire name of an error code: "invalid_argument", "not_found", ….
std::string_view ErrorCodeName(ErrorCode code);
/// The code of a wire name; nullopt for a name no code has.
std::optional<ErrorCode> ParseErrorCode(std::string_view name);

class [[nodiscard]] Status {
 public:
  Status() = default;  // OK
  Status(ErrorCode code, std::string message, std::string field = {})
      : code_(code), message_(std::move(message)), field_(std::move(field)) {}

  static Status Ok() { return {}; }
  static Status InvalidArgument(std::string message, std::string field = {}) {
    return {ErrorCode::kInvalidArgument, std::move(message), std::move(field)};
  }
  static Status NotFound(std::string message) { return {ErrorCode::kNotFound, std::move(message)}; }
  static Status AlreadyExists(std::string message, std::string field = {}) {
    return {ErrorCode::kAlreadyExists, std::move(message), std::move(field)};
  }
  static Status Conflict(std::string message) { return {ErrorCode::kConflict, std::move(message)}; }
  static Status FailedPrecondition(std::string message) {
    return {ErrorCode::kFailedPrecondition, std::move(message)};
  }
  static Status Unavailable(std::string message) {
    return {ErrorCode::kUnavailable, std::move(message)};
  }
  static Status PayloadTooLarge(std::string message, std::string field = {}) {
    return {ErrorCode::kPayloadTooLarge, std::move(message), std::move(field)};
  }
  static Status DataLoss(std::string message) { return {ErrorCode::kDataLoss, std::move(message)}; }
  static Status Internal(std::string message) { return {ErrorCode::kInternal, std::move(message)}; }

  bool ok() const { return code_ == ErrorCode::kOk; }
  ErrorCode code() const { return code_; }
  const std::string& message() const { return message_; }
  /// The offending input field as a dotted path ("passive.inertia_kgm2"), or
  /// empty when no single field is at fault.
  const std::string& field() const { return field_; }

  /// "invalid_argument: passive.inertia_kgm2: must be positive".
  std::string ToString() const;

 private:
  ErrorCode code_ = ErrorCode::kOk;
  std::string message_;
  std::string field_;
};

/// A value or the Status saying why there is none.
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : value_(std::move(value)) {}  // NOLINT: implicit by design
  Result(Status status) : status_(std::move(status)) {  // NOLINT
    assert(!status_.ok() && "Result built from an OK status");
  }

  bool ok() const { return value_.has_value(); }
  const Status& status() const { return status_; }
  const T& value() const& { assert(ok()); return *value_; }
  T& value() & { assert(ok()); return *value_; }
  T&& value() && { assert(ok()); return *std::move(value_); }
  const T& operator*() const& { return value(); }
  T& operator*() & { return value(); }
  const T* operator->() const { return &value(); }
  T* operator->() { return &value(); }

 private:
  std::optional<T> value_;
  Status status_;
};

}  // namespace fesbench::api
