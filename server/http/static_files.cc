#include "server/http/static_files.h"

#include <array>
#include <fstream>
#include <iterator>
#include <sstream>
#include <utility>

namespace fesbench::server::http {

namespace {

bool IsSafeSegment(std::string_view segment) {
  if (segment.empty() || segment.size() > 128 || segment.front() == '.') return false;
  for (char c : segment) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '.' || c == '_' || c == '-';
    if (!ok) return false;
  }
  return true;
}

// True if `path` is `root` or lies below it (both canonical).
bool IsInside(const std::filesystem::path& root, const std::filesystem::path& path) {
  auto r = root.begin();
  auto p = path.begin();
  for (; r != root.end(); ++r, ++p) {
    if (p == path.end() || *r != *p) return false;
  }
  return true;
}

}  // namespace

std::string_view ContentTypeFor(std::string_view file_name) {
  static constexpr std::array<std::pair<std::string_view, std::string_view>, 12> kTypes{{
      {".html", "text/html; charset=utf-8"},
      {".js", "text/javascript; charset=utf-8"},
      {".mjs", "text/javascript; charset=utf-8"},
      {".css", "text/css; charset=utf-8"},
      {".json", "application/json"},
      {".map", "application/json"},
      {".svg", "image/svg+xml"},
      {".png", "image/png"},
      {".ico", "image/x-icon"},
      {".txt", "text/plain; charset=utf-8"},
      {".woff2", "font/woff2"},
      {".webmanifest", "application/manifest+json"},
  }};
  const auto dot = file_name.rfind('.');
  if (dot == std::string_view::npos) return "application/octet-stream";
  const std::string_view ext = file_name.substr(dot);
  for (const auto& [e, type] : kTypes) {
    if (e == ext) return type;
  }
  return "application/octet-stream";
}

bool IsHashedAssetName(std::string_view file_name) {
  const auto dot = file_name.rfind('.');
  const auto dash = file_name.rfind('-', dot);
  if (dot == std::string_view::npos || dash == std::string_view::npos || dot - dash - 1 < 8) {
    return false;
  }
  for (char c : file_name.substr(dash + 1, dot - dash - 1)) {
    if (!((c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9'))) return false;
  }
  return true;
}

StaticFiles::StaticFiles(std::filesystem::path root) {
  std::error_code ec;
  auto canonical = std::filesystem::canonical(root, ec);
  if (!ec && std::filesystem::is_directory(canonical, ec)) root_ = std::move(canonical);
}

std::optional<std::filesystem::path> StaticFiles::Resolve(std::string_view request_path) const {
  if (root_.empty() || request_path.empty() || request_path.front() != '/') return std::nullopt;
  if (request_path == "/") request_path = "/index.html";
  std::filesystem::path path = root_;
  std::string_view rest = request_path.substr(1);
  while (true) {
    const auto slash = rest.find('/');
    const std::string_view segment = rest.substr(0, slash);
    if (!IsSafeSegment(segment)) return std::nullopt;
    path /= std::string(segment);
    if (slash == std::string_view::npos) break;
    rest = rest.substr(slash + 1);
  }
  std::error_code ec;
  auto canonical = std::filesystem::canonical(path, ec);
  if (ec || !IsInside(root_, canonical) || !std::filesystem::is_regular_file(canonical, ec)) {
    return std::nullopt;
  }
  return canonical;
}

bool StaticFiles::Serve(const Request& req, Response& res) const {
  if (req.method != "GET" && req.method != "HEAD") return false;
  if (req.path == "/api" || req.path.rfind("/api/", 0) == 0) return false;
  auto file = Resolve(req.path);
  if (!file) return false;
  std::ifstream in(*file, std::ios::binary);
  std::string body((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) return false;
  const std::string name = file->filename().string();
  res.status = 200;
  res.headers.erase("Cache-Control");  // the server's default is no-store
  res.set_header("Cache-Control", IsHashedAssetName(name) ? "public, max-age=31536000, immutable"
                                                          : "no-cache");
  if (name.ends_with(".html")) {
    // The bundle loads nothing from elsewhere; say so to the browser too.
    res.set_header("Content-Security-Policy",
                   "default-src 'self'; img-src 'self' data:; style-src 'self' 'unsafe-inline'; "
                   "connect-src 'self'; frame-ancestors 'none'; base-uri 'none'; form-action 'self'");
    res.set_header("X-Frame-Options", "DENY");
  }
  res.set_content(std::move(body), std::string(ContentTypeFor(name)));
  return true;
}

}  // namespace fesbench::server::http
