#include "api/status.h"

#include "api/name_table.h"

namespace fesbench::api {

namespace {

constexpr NameTable<ErrorCode, 12> kErrorCodes(
    {{{ErrorCode::kOk, "ok"},
      {ErrorCode::kInvalidArgument, "invalid_argument"},
      {ErrorCode::kNotFound, "not_found"},
      {ErrorCode::kAlreadyExists, "already_exists"},
      {ErrorCode::kConflict, "conflict"},
      {ErrorCode::kFailedPrecondition, "failed_precondition"},
      {ErrorCode::kUnauthenticated, "unauthenticated"},
      {ErrorCode::kPermissionDenied, "permission_denied"},
      {ErrorCode::kUnavailable, "unavailable"},
      {ErrorCode::kPayloadTooLarge, "payload_too_large"},
      {ErrorCode::kDataLoss, "data_loss"},
      {ErrorCode::kInternal, "internal"}}},
    "internal");

}  // namespace

std::string_view ErrorCodeName(ErrorCode code) { return kErrorCodes.Name(code); }

std::optional<ErrorCode> ParseErrorCode(std::string_view name) { return kErrorCodes.Parse(name); }

std::string Status::ToString() const {
  if (ok()) return "ok";
  std::string s(ErrorCodeName(code_));
  s += ": ";
  if (!field_.empty()) s += field_ + ": ";
  s += message_;
  return s;
}

}  // namespace fesbench::api
