#pragma once

/// @file
/// The one place where an api::Status becomes an HTTP status and a JSON
/// error body (docs/API.md, "HTTP conventions"):
///   {"error": {"code": "not_found", "message": "subject 7 not found",
///              "field": "subject_id"}}     ("field" only when one is at fault)
///
/// Mapping (documented in the OpenAPI document and the README):
///   invalid_argument                          400 (every validation failure,
///                                                  syntactic or semantic)
///   unauthenticated                           401
///   permission_denied                         403
///   not_found                                 404
///   already_exists, conflict,
///   failed_precondition                       409
///   payload_too_large                         413 (an upload beyond a limit)
///   unavailable                               503 (real overload only)
///   data_loss, internal                       500 (never caused by client input)
/// Transport-level refusals that have no api::ErrorCode use HttpError
/// directly: 405 method_not_allowed, 411 length_required (chunked request
/// bodies), 413 payload_too_large, 415 unsupported_media_type,
/// 431 too_many_headers.

#include "server/http/message.h"

#include <nlohmann/json.hpp>
#include <string>

#include "api/status.h"

namespace fesbench::server::http {

/// An error as it goes out: HTTP status, wire code, message, field.
struct HttpError {
  int http_status = 500;
  std::string code;  ///< e.g. "not_found", "payload_too_large".
  std::string message;
  std::string field;  ///< dotted path of the offending field, or empty.
};

/// The HTTP status for an error code (table above); 200 for kOk.
int HttpStatusFor(api::ErrorCode code);
/// The HttpError for a non-OK status.
HttpError ToHttpError(const api::Status& status);
/// {"error": {"code", "message", "field"?}}.
nlohmann::json ErrorJson(const HttpError& error);
/// Sets status, JSON body and Content-Type on `res`.
void WriteError(Response& res, const HttpError& error);
void WriteError(Response& res, const api::Status& status);
/// Sets `res` to `status` with a JSON body (serialised compactly).
void WriteJson(Response& res, int status, const nlohmann::json& body);

}  // namespace fesbench::server::http
