#include "server/http/response_writer.h"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <climits>
#include <cstdio>

#include "server/http/errors.h"

namespace fesbench::server::http {

namespace {

// Echo at most a short prefix of client text in messages.
std::string Clip(std::string_view text, std::size_t n = 120) {
  return text.size() <= n ? std::string(text) : std::string(text.substr(0, n)) + "…";
}

// The JSON error of a status the front end set without a body.
HttpError BodilessError(const Request& req, int status) {
  switch (status) {
    case 404:
      return {404, "not_found", "no route for " + Clip(req.method) + " " + Clip(req.path), {}};
    case 416:
      return {416, "range_not_satisfiable", "invalid Range header", {}};
    default:
      if (status >= 500) return {status, "internal", "internal server error", {}};
      return {status, "bad_request", "request refused", {}};
  }
}

// Media types worth compressing: text (but not event streams, whose frames
// must leave as they are written) and the structured types.
bool Compresses(std::string_view media_type) {
  constexpr std::array<std::string_view, 6> kTypes = {
      "image/svg+xml",    "application/javascript", "application/json",
      "application/xml",  "application/protobuf",   "application/xhtml+xml"};
  if (std::find(kTypes.begin(), kTypes.end(), media_type) != kTypes.end()) return true;
  return media_type.starts_with("text/") && media_type != "text/event-stream";
}

// `data` as one gzip member (RFC 1952) at zlib's default level; false if
// zlib fails.
bool Gzip(std::string_view data, std::string& out) {
  z_stream stream{};
  if (deflateInit2(&stream, Z_DEFAULT_COMPRESSION, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) !=
      Z_OK) {
    return false;
  }
  std::array<char, 16384> buffer{};
  bool ok = true;
  do {
    const std::size_t take = std::min<std::size_t>(data.size(), UINT_MAX);
    stream.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
    stream.avail_in = static_cast<uInt>(take);
    data.remove_prefix(take);
    const int flush = data.empty() ? Z_FINISH : Z_NO_FLUSH;
    do {
      stream.next_out = reinterpret_cast<Bytef*>(buffer.data());
      stream.avail_out = static_cast<uInt>(buffer.size());
      if (deflate(&stream, flush) == Z_STREAM_ERROR) ok = false;
      out.append(buffer.data(), buffer.size() - stream.avail_out);
    } while (ok && stream.avail_out == 0);
  } while (ok && !data.empty());
  deflateEnd(&stream);
  return ok;
}

void CompressBody(const Request& req, Response& res) {
  if (!Compresses(res.get_header_value("Content-Type"))) return;
  if (req.get_header_value("Accept-Encoding").find("gzip") == std::string::npos) return;
  std::string compressed;
  if (!Gzip(res.body, compressed)) return;
  res.body.swap(compressed);
  res.set_header("Content-Encoding", "gzip");
}

}  // namespace

std::string FinishResponse(const Request& req, Response& res, bool close,
                           const KeepAliveTerms& terms) {
  if (res.status >= 400 && res.body.empty() && !res.events) {
    WriteError(res, BodilessError(req, res.status));
  }
  if (res.events) {
    res.set_header("Transfer-Encoding", "chunked");
  } else if (!res.body.empty()) {
    CompressBody(req, res);
    res.set_header("Content-Length", std::to_string(res.body.size()));
  }
  if (close || req.get_header_value("Connection") == "close") {
    res.set_header("Connection", "close");
  } else {
    res.set_header("Keep-Alive", "timeout=" + std::to_string(terms.timeout.count()) +
                                     ", max=" + std::to_string(terms.max_count));
  }
  if (!res.has_header("Content-Type") && (!res.body.empty() || res.events)) {
    res.set_header("Content-Type", "text/plain");
  }
  if (!res.has_header("Content-Length") && res.body.empty() && !res.events) {
    res.set_header("Content-Length", "0");
  }
  if (!res.has_header("Accept-Ranges") && req.method == "HEAD") {
    res.set_header("Accept-Ranges", "bytes");
  }
  std::string head = "HTTP/1.1 " + std::to_string(res.status) + " " + ReasonPhrase(res.status) + "\r\n";
  for (const auto& [name, value] : res.headers) head += name + ": " + value + "\r\n";
  head += "\r\n";
  return head;
}

std::string EventChunk(std::string_view data) {
  char size[20];
  std::snprintf(size, sizeof size, "%zx\r\n", data.size());
  std::string chunk = size;
  chunk.append(data);
  chunk += "\r\n";
  return chunk;
}

}  // namespace fesbench::server::http
