#include "server/http/errors.h"

namespace fesbench::server::http {

int HttpStatusFor(api::ErrorCode code) {
  using api::ErrorCode;
  switch (code) {
    case ErrorCode::kOk:
      return 200;
    case ErrorCode::kInvalidArgument:
      return 400;
    case ErrorCode::kUnauthenticated:
      return 401;
    case ErrorCode::kPermissionDenied:
      return 403;
    case ErrorCode::kNotFound:
      return 404;
    case ErrorCode::kAlreadyExists:
    case ErrorCode::kConflict:
    case ErrorCode::kFailedPrecondition:
      return 409;
    case ErrorCode::kUnavailable:
      return 503;
    case ErrorCode::kPayloadTooLarge:
      return 413;
    case ErrorCode::kDataLoss:
    case ErrorCode::kInternal:
      return 500;
  }
  return 500;
}

HttpError ToHttpError(const api::Status& status) {
  return {HttpStatusFor(status.code()), std::string(api::ErrorCodeName(status.code())),
          status.message(), status.field()};
}

nlohmann::json ErrorJson(const HttpError& error) {
  nlohmann::json body = {{"code", error.code}, {"message", error.message}};
  if (!error.field.empty()) body["field"] = error.field;
  return {{"error", std::move(body)}};
}

void WriteJson(Response& res, int status, const nlohmann::json& body) {
  res.status = status;
  // Replace invalid UTF-8 (from echoed client input) rather than throw.
  res.set_content(body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace),
                  "application/json");
}

void WriteError(Response& res, const HttpError& error) {
  WriteJson(res, error.http_status, ErrorJson(error));
  // Every 503 is a momentary refusal (busy, full, shutting down): say when to retry.
  if (error.http_status == 503 && !res.has_header("Retry-After")) res.set_header("Retry-After", "1");
}

void WriteError(Response& res, const api::Status& status) {
  WriteError(res, ToHttpError(status));
}

}  // namespace fesbench::server::http
