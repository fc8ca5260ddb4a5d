#include "server/http/request_parser.h"

#include <boost/asio/buffer.hpp>
#include <boost/beast/http/parser.hpp>
#include <boost/beast/http/string_body.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdint>
#include <limits>
#include <string>

namespace fesbench::server::http {

namespace {

namespace beast_http = boost::beast::http;

bool IsServedMethod(std::string_view method) {
  constexpr std::array<std::string_view, 7> kServed = {"GET", "HEAD",  "POST",   "PUT",
                                                       "DELETE", "PATCH", "OPTIONS"};
  return std::find(kServed.begin(), kServed.end(), method) != kServed.end();
}

bool IsRefusedMethod(std::string_view method) {
  return method == "CONNECT" || method == "TRACE" || method == "PRI";
}

HttpError Malformed() { return {400, "bad_request", "malformed HTTP request", {}}; }

// "http://host/path" → "/path" (the host is ours, whatever it says).
std::string OriginForm(std::string path) {
  for (std::string_view scheme : {"http://", "https://"}) {
    if (path.size() >= scheme.size() &&
        std::equal(scheme.begin(), scheme.end(), path.begin(), [](char a, char b) {
          return a == std::tolower(static_cast<unsigned char>(b));
        })) {
      const std::size_t slash = path.find('/', scheme.size());
      return slash == std::string::npos ? "/" : path.substr(slash);
    }
  }
  return path;
}

bool AllDigits(std::string_view text) {
  return std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; });
}

}  // namespace

std::optional<HttpError> ParseRequest(std::string_view bytes, Request& req) {
  beast_http::request_parser<beast_http::string_body> parser;
  parser.eager(true);
  parser.header_limit(static_cast<std::uint32_t>(std::min<std::size_t>(
      bytes.size() + 1, std::numeric_limits<std::uint32_t>::max())));
  parser.body_limit(bytes.size());
  boost::beast::error_code error;
  std::size_t used = 0;
  while (!error && !parser.is_done() && used < bytes.size()) {
    used += parser.put(boost::asio::buffer(bytes.data() + used, bytes.size() - used), error);
  }
  if (!error && !parser.is_done()) parser.put_eof(error);
  if (error || !parser.is_done()) return Malformed();

  auto& message = parser.get();
  req.method = std::string(message.method_string());
  if (!IsServedMethod(req.method)) {
    if (IsRefusedMethod(req.method)) {
      return HttpError{405, "method_not_allowed", "method " + req.method + " is not supported", {}};
    }
    return Malformed();
  }
  if (message.version() != 11 && message.version() != 10) return Malformed();
  req.version = message.version() == 11 ? "HTTP/1.1" : "HTTP/1.0";
  req.target = std::string(message.target());
  for (const auto& field : message) {
    // A field with an empty value is as good as absent (an empty Range is
    // no range).
    if (field.value().empty()) continue;
    req.headers.emplace(std::string(field.name_string()), std::string(field.value()));
  }
  req.body = std::move(message.body());

  const std::string_view target = std::string_view(req.target).substr(0, req.target.find('#'));
  const std::size_t question = target.find('?');
  req.path = OriginForm(DecodeUrl(target.substr(0, question), false));
  if (question != std::string_view::npos) {
    const std::string_view query = target.substr(question + 1);
    if (query.find('?') != std::string_view::npos) return Malformed();
    ParseQuery(query, req.params);
  }
  return std::nullopt;
}

bool IsValidRange(std::string_view value) {
  if (!value.starts_with("bytes=")) return false;
  std::string_view ranges = value.substr(6);
  for (bool first_range = true;; first_range = false) {
    const std::size_t comma = ranges.find(',');
    std::string_view range = ranges.substr(0, comma);
    if (!first_range) {
      while (!range.empty() && std::isspace(static_cast<unsigned char>(range.front()))) {
        range.remove_prefix(1);
      }
    }
    const std::size_t dash = range.find('-');
    if (dash == std::string_view::npos) return false;
    const std::string_view first = range.substr(0, dash), last = range.substr(dash + 1);
    if (!AllDigits(first) || !AllDigits(last)) return false;
    if (!first.empty() && !last.empty()) {
      if (first.size() > 18 || last.size() > 18) return false;
      if (std::stoll(std::string(first)) > std::stoll(std::string(last))) return false;
    }
    if (comma == std::string_view::npos) return true;
    ranges.remove_prefix(comma + 1);
  }
}

}  // namespace fesbench::server::http
