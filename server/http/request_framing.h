#pragma once

/// @file
/// Request framing for the HTTP front end (http_server.h): finds where one
/// HTTP/1.1 request in a connection's received bytes ends, before any of it
/// reaches a handler. The front end buffers a whole request (head and body)
/// under a deadline and hands exactly those bytes on, so a slow client never
/// holds a worker thread, pipelined requests are answered one after
/// another, and a request is answered even when the client half-closed.
///
/// Strict on purpose (RFC 9112): lines end in CRLF; no obsolete line
/// folding; Content-Length is decimal digits and at most one value;
/// Transfer-Encoding is refused (411: request bodies must carry
/// Content-Length); GET and HEAD take no body. Empty lines before the
/// request line are skipped.

#include <cstddef>
#include <string_view>

#include "server/http/errors.h"

namespace fesbench::server::http {

struct FramingLimits {
  std::size_t max_head_bytes = 16 * 1024;  ///< request line and headers; beyond: 431.
  std::size_t max_target_bytes = 8 * 1024;  ///< request target; beyond: 414.
  std::size_t max_headers = 64;             ///< header lines; beyond: 431.
  std::size_t max_body_bytes = 1 << 20;     ///< Content-Length beyond: 413.
  /// Uploads (POST /api/v1/sessions/{id}/trials: recordings and session
  /// archives) may be larger, up to this.
  std::size_t max_upload_bytes = std::size_t{256} << 20;
};

/// True for the requests whose body is an upload (FramingLimits::max_upload_bytes).
bool IsUpload(std::string_view method, std::string_view path);

struct Framing {
  enum class State { kIncomplete, kComplete, kError };
  State state = State::kIncomplete;
  HttpError error;  ///< kError: the answer (the connection is closed after it).

  std::size_t skip = 0;        ///< empty lines before the request line.
  bool head_complete = false;  ///< the blank line after the headers has arrived.
  std::size_t head_bytes = 0;  ///< request line to blank line (head_complete).
  std::size_t body_bytes = 0;  ///< Content-Length (head_complete).
  bool keep_alive = true;      ///< false: "Connection: close", or HTTP/1.0 without keep-alive.
  bool expect_continue = false;  ///< "Expect: 100-continue".
  std::string_view method;       ///< head_complete: the request method.
  std::string_view path;  ///< head_complete: the target's path (origin form, before '?').
  std::string_view authorization;  ///< head_complete: the Authorization header's value, if any.
  std::string_view content_type;   ///< head_complete: the Content-Type header's value, if any.
  bool upload = false;  ///< head_complete: an upload (IsUpload), held to max_upload_bytes.

  /// Bytes of the whole request from the start of the buffer (kComplete).
  std::size_t total() const { return skip + head_bytes + body_bytes; }
};

/// Frames the first request in `buffer` (the connection's unread bytes).
/// kIncomplete: more bytes are needed (the fields set so far are valid);
/// kComplete: `total()` bytes form the request; kError: refuse with `error`.
Framing FrameRequest(std::string_view buffer, const FramingLimits& limits);

}  // namespace fesbench::server::http
