#pragma once

/// @file
/// Turns a handled Response (message.h) into the bytes of an HTTP/1.1
/// answer (docs/API.md, "HTTP conventions"): status line and header fields
/// in name order, Content-Length (or chunked transfer for event streams),
/// Connection: close or the keep-alive terms, gzip for compressible bodies
/// when the client accepts it. The front end (http_server.h) sends them.

#include <chrono>
#include <cstddef>
#include <string>
#include <string_view>

#include "server/http/message.h"

namespace fesbench::server::http {

/// What the server tells a client it may keep a connection for.
struct KeepAliveTerms {
  std::chrono::seconds timeout{5};
  std::size_t max_count = 10000;
};

/// Completes `res` for `req` (an error status without a body gets the JSON
/// error body; a body is gzip-compressed if the client accepts gzip and the
/// media type compresses; framing and connection headers are added) and
/// returns its head (status line, fields, blank line). `close`: the
/// connection is closed after this answer. The body to send is `res.body`
/// unless `req` is a HEAD or `res` is an event stream (EventChunk).
std::string FinishResponse(const Request& req, Response& res, bool close,
                           const KeepAliveTerms& terms);

/// One chunk of a chunked body carrying `data` (non-empty).
std::string EventChunk(std::string_view data);
/// The chunk that ends a chunked body.
inline constexpr std::string_view kLastChunk = "0\r\n\r\n";

}  // namespace fesbench::server::http
