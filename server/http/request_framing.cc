#include "server/http/request_framing.h"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <optional>
#include <string>

namespace fesbench::server::http {

namespace {

bool IsTokenChar(char c) {
  const auto u = static_cast<unsigned char>(c);
  if (std::isalnum(u)) return true;
  switch (c) {
    case '!':
    case '#':
    case '$':
    case '%':
    case '&':
    case '\'':
    case '*':
    case '+':
    case '-':
    case '.':
    case '^':
    case '_':
    case '`':
    case '|':
    case '~':
      return true;
    default:
      return false;
  }
}

bool EqualsIgnoreCase(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(a[i])) !=
        std::tolower(static_cast<unsigned char>(b[i]))) {
      return false;
    }
  }
  return true;
}

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

// Whether a comma-separated header value holds `token` (case-insensitive).
bool HasToken(std::string_view value, std::string_view token) {
  while (!value.empty()) {
    const std::size_t comma = value.find(',');
    if (EqualsIgnoreCase(Trim(value.substr(0, comma)), token)) return true;
    if (comma == std::string_view::npos) break;
    value.remove_prefix(comma + 1);
  }
  return false;
}

// Decimal digits only; nullopt when empty, not digits, or beyond uint64.
std::optional<std::uint64_t> ParseLength(std::string_view text) {
  if (text.empty() || text.size() > 20) return std::nullopt;
  std::uint64_t value = 0;
  for (char c : text) {
    if (c < '0' || c > '9') return std::nullopt;
    const std::uint64_t digit = static_cast<std::uint64_t>(c - '0');
    if (value > (UINT64_MAX - digit) / 10) return std::nullopt;
    value = value * 10 + digit;
  }
  return value;
}

Framing Fail(Framing f, int status, const char* code, std::string message) {
  f.state = Framing::State::kError;
  f.error = HttpError{status, code, std::move(message), {}};
  return f;
}

// The path of an origin-form or absolute-form target, before '?'.
std::string_view TargetPath(std::string_view target) {
  for (std::string_view scheme : {"http://", "https://"}) {
    if (target.size() >= scheme.size() &&
        EqualsIgnoreCase(target.substr(0, scheme.size()), scheme)) {
      const std::size_t slash = target.find('/', scheme.size());
      target = slash == std::string_view::npos ? std::string_view("/") : target.substr(slash);
      break;
    }
  }
  return target.substr(0, target.find('?'));
}

}  // namespace

Framing FrameRequest(std::string_view buffer, const FramingLimits& limits) {
  Framing f;
  while (buffer.substr(f.skip, 2) == "\r\n") f.skip += 2;
  const std::string_view rest = buffer.substr(f.skip);

  // Line endings as far as the bytes go: CRLF only, no NUL.
  const std::size_t scan = std::min(rest.size(), limits.max_head_bytes + 4);
  std::size_t head_end = std::string_view::npos;
  for (std::size_t i = 0; i < scan; ++i) {
    const char c = rest[i];
    if (c == '\0') return Fail(f, 400, "bad_request", "NUL byte in the request head");
    if (c == '\n' && (i == 0 || rest[i - 1] != '\r')) {
      return Fail(f, 400, "bad_request", "request head lines must end in CRLF");
    }
    if (c == '\r' && i + 1 < rest.size() && rest[i + 1] != '\n') {
      return Fail(f, 400, "bad_request", "bare CR in the request head");
    }
    if (c == '\n' && i >= 3 && rest[i - 2] == '\n') {
      head_end = i + 1;
      break;
    }
  }
  const std::size_t first_eol = rest.substr(0, scan).find("\r\n");
  if (first_eol == std::string_view::npos && rest.size() > limits.max_target_bytes + 32) {
    return Fail(f, 414, "uri_too_long", "request line too long");
  }
  if (head_end == std::string_view::npos) {
    if (rest.size() > limits.max_head_bytes) {
      return Fail(f, 431, "too_many_headers",
                  "request head exceeds " + std::to_string(limits.max_head_bytes) + " bytes");
    }
    return f;
  }
  f.head_complete = true;
  f.head_bytes = head_end;

  // Request line: method SP target SP version.
  const std::string_view line = rest.substr(0, first_eol);
  const std::size_t sp1 = line.find(' ');
  const std::size_t sp2 = sp1 == std::string_view::npos ? sp1 : line.find(' ', sp1 + 1);
  if (sp1 == std::string_view::npos || sp2 == std::string_view::npos ||
      line.find(' ', sp2 + 1) != std::string_view::npos) {
    return Fail(f, 400, "bad_request", "malformed request line");
  }
  f.method = line.substr(0, sp1);
  const std::string_view target = line.substr(sp1 + 1, sp2 - sp1 - 1);
  const std::string_view version = line.substr(sp2 + 1);
  if (f.method.empty() || f.method.size() > 32 ||
      !std::all_of(f.method.begin(), f.method.end(), IsTokenChar)) {
    return Fail(f, 400, "bad_request", "malformed request method");
  }
  if (target.size() > limits.max_target_bytes) {
    return Fail(f, 414, "uri_too_long", "request line too long");
  }
  if (target.empty() || std::any_of(target.begin(), target.end(), [](char c) {
        return static_cast<unsigned char>(c) <= 0x20 || c == 0x7f;
      })) {
    return Fail(f, 400, "bad_request", "malformed request target");
  }
  if (version != "HTTP/1.1" && version != "HTTP/1.0") {
    return Fail(f, 400, "bad_request", "unsupported HTTP version (HTTP/1.1 and 1.0 are)");
  }
  f.path = TargetPath(target);
  const bool http10 = version == "HTTP/1.0";
  bool keep_alive_token = false, close_token = false;

  // Header lines.
  std::optional<std::uint64_t> length;
  std::size_t count = 0;
  std::size_t pos = first_eol + 2;
  while (pos + 2 < head_end) {
    const std::size_t eol = rest.find("\r\n", pos);
    const std::string_view header = rest.substr(pos, eol - pos);
    pos = eol + 2;
    if (++count > limits.max_headers) {
      return Fail(f, 431, "too_many_headers",
                  "at most " + std::to_string(limits.max_headers) + " header lines are accepted");
    }
    if (header.front() == ' ' || header.front() == '\t') {
      return Fail(f, 400, "bad_request", "folded header lines are not accepted");
    }
    const std::size_t colon = header.find(':');
    const std::string_view name = header.substr(0, colon);
    if (colon == std::string_view::npos || name.empty() ||
        !std::all_of(name.begin(), name.end(), IsTokenChar)) {
      return Fail(f, 400, "bad_request", "malformed header line");
    }
    const std::string_view value = Trim(header.substr(colon + 1));
    if (std::any_of(value.begin(), value.end(), [](char c) {
          return (static_cast<unsigned char>(c) < 0x20 && c != '\t') || c == 0x7f;
        })) {
      return Fail(f, 400, "bad_request", "control character in header " + std::string(name));
    }
    if (EqualsIgnoreCase(name, "content-length")) {
      const auto parsed = ParseLength(value);
      if (!parsed) {
        const bool digits = !value.empty() && std::all_of(value.begin(), value.end(), [](char c) {
          return c >= '0' && c <= '9';
        });
        if (digits) {
          return Fail(f, 413, "payload_too_large", "request body exceeds the server's limit");
        }
        return Fail(f, 400, "bad_request", "invalid Content-Length (decimal digits expected)");
      }
      if (length && *length != *parsed) {
        return Fail(f, 400, "bad_request", "conflicting Content-Length headers");
      }
      length = parsed;
    } else if (EqualsIgnoreCase(name, "transfer-encoding")) {
      return Fail(f, 411, "length_required",
                  "request bodies sent with Transfer-Encoding (chunked) are not accepted; send "
                  "Content-Length");
    } else if (EqualsIgnoreCase(name, "connection")) {
      close_token = close_token || HasToken(value, "close");
      keep_alive_token = keep_alive_token || HasToken(value, "keep-alive");
    } else if (EqualsIgnoreCase(name, "expect")) {
      f.expect_continue = EqualsIgnoreCase(value, "100-continue");
    } else if (EqualsIgnoreCase(name, "authorization")) {
      f.authorization = value;
    } else if (EqualsIgnoreCase(name, "content-type")) {
      f.content_type = value;
    }
  }
  f.keep_alive = !close_token && (!http10 || keep_alive_token);
  f.body_bytes = length.value_or(0);
  f.upload = IsUpload(f.method, f.path);
  const std::size_t max_body = f.upload ? limits.max_upload_bytes : limits.max_body_bytes;
  if (f.body_bytes > max_body) {
    return Fail(f, 413, "payload_too_large",
                "request body exceeds the server's limit of " + std::to_string(max_body >> 20) +
                    " MiB" + (f.upload ? " for uploads" : ""));
  }
  if ((f.method == "GET" || f.method == "HEAD") && f.body_bytes > 0) {
    return Fail(f, 400, "bad_request", "GET requests take no body");
  }
  if (rest.size() >= f.head_bytes + f.body_bytes) f.state = Framing::State::kComplete;
  return f;
}

bool IsUpload(std::string_view method, std::string_view path) {
  constexpr std::string_view kPrefix = "/api/v1/sessions/";
  constexpr std::string_view kSuffix = "/trials";
  if (method != "POST" || !path.starts_with(kPrefix) || !path.ends_with(kSuffix)) return false;
  const std::string_view id =
      path.substr(kPrefix.size(), path.size() - kPrefix.size() - kSuffix.size());
  return !id.empty() &&
         std::all_of(id.begin(), id.end(), [](char c) { return c >= '0' && c <= '9'; });
}

}  // namespace fesbench::server::http
