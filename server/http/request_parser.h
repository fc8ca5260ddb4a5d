#pragma once

/// @file
/// Turns one framed request (request_framing.h: exactly its bytes, head and
/// body) into a Request (message.h). Boost.Beast's request parser reads the
/// request line, the header fields and the body; this adds what the API
/// needs on top: the path percent-decoded, absolute-form targets reduced to
/// their path (RFC 9112 §3.2.2), the query decoded into parameters.

#include <optional>
#include <string_view>

#include "server/http/errors.h"
#include "server/http/message.h"

namespace fesbench::server::http {

/// Fills `req` (method, target, path, version, headers, params, body) from
/// `bytes`. The refusal for a request that is not well-formed HTTP/1.x
/// (400), or whose method the API does not serve (405).
std::optional<HttpError> ParseRequest(std::string_view bytes, Request& req);

/// Whether a Range header value is well-formed ("bytes=" and ranges with
/// first ≤ last). The API never answers with a part of a resource, but an
/// ill-formed Range is refused (416).
bool IsValidRange(std::string_view value);

}  // namespace fesbench::server::http
