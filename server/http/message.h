#pragma once

/// @file
/// One HTTP request and its response as the route handlers see them
/// (docs/ARCHITECTURE.md, "The HTTP front end"): plain data, filled by the
/// front end from a framed request (request_framing.h) and written by it to
/// the connection (http_server.h). Nothing here touches a socket.
///
/// The member names follow the ones the handlers were first written against
/// (method, path, headers, params, body; status, set_content, set_header),
/// so a handler reads the same either way.

#include <functional>
#include <map>
#include <string>
#include <string_view>

namespace fesbench::server::http {

/// Header names compare case-insensitively (RFC 9110 §5.1).
struct CaseInsensitiveLess {
  using is_transparent = void;
  bool operator()(std::string_view a, std::string_view b) const;
};

/// Header fields in name order (case aside), repeated names in arrival order.
using Headers = std::multimap<std::string, std::string, CaseInsensitiveLess>;
/// Query parameters, decoded ('+' is a space).
using Params = std::multimap<std::string, std::string, std::less<>>;

struct Request {
  std::string method;   ///< "GET", "POST", …
  std::string target;   ///< the request target as sent.
  std::string path;     ///< the target's path, percent-decoded (origin form).
  std::string version;  ///< "HTTP/1.1" or "HTTP/1.0".
  Headers headers;
  Params params;
  std::string body;  ///< empty for uploads (RequestContext::upload).
  std::string remote_addr;
  int remote_port = 0;

  bool has_header(std::string_view name) const;
  /// The first value of header `name`, or "".
  std::string get_header_value(std::string_view name) const;
  bool has_param(const std::string& name) const;
  /// The first value of query parameter `name`, or "".
  std::string get_param_value(const std::string& name) const;
};

/// Where an event stream's frames go (Response::set_event_stream).
struct EventSink {
  /// Sends `data` at once; false once the client has gone.
  std::function<bool(std::string_view data)> write;
  /// Ends the stream (the front end stops calling the source).
  std::function<void()> done;
};

/// Called again and again by the front end while the stream is open and the
/// server runs; each call may write frames or wait briefly for them. False:
/// abandon the stream (the client left).
using EventSource = std::function<bool(EventSink& sink)>;

struct Response {
  int status = -1;  ///< -1: not set (200 once routed).
  Headers headers;
  std::string body;
  /// Set for event streams (text/event-stream, sent chunked): the body is
  /// produced by this source instead of `body`.
  EventSource events;

  bool has_header(std::string_view name) const;
  std::string get_header_value(std::string_view name) const;
  /// Adds a header field (a repeated name adds another line); refused if
  /// the name or value holds CR or LF.
  void set_header(const std::string& name, const std::string& value);
  /// Sets the body and its Content-Type.
  void set_content(std::string content, const std::string& content_type);
  /// Makes the response an event stream of `content_type` fed by `source`.
  void set_event_stream(const std::string& content_type, EventSource source);
};

/// Percent-decodes `text` (%XX; with `plus_is_space`, '+' is a space, as in
/// a query). A '%' without two hex digits stays as it is.
std::string DecodeUrl(std::string_view text, bool plus_is_space);

/// Adds the parameters of a query string ("a=1&b=2") to `params`: pieces
/// trimmed of spaces, empty pieces and names skipped, a repeated
/// "name=value" piece kept once.
void ParseQuery(std::string_view query, Params& params);

/// The reason phrase of an HTTP status (RFC 9110 §15).
const char* ReasonPhrase(int status);

}  // namespace fesbench::server::http
