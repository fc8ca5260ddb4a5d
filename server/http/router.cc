#include "server/http/router.h"

#include <algorithm>
#include <cassert>

namespace fesbench::server::http {

namespace {

bool IsIdName(std::string_view name) {
  return name.size() >= 2 && name.substr(name.size() - 2) == "id";
}

bool MatchesParam(std::string_view name, std::string_view segment) {
  if (segment.empty() || segment.size() > 64) return false;
  if (IsIdName(name)) {
    if (segment.size() > 18 || segment[0] == '0') return false;
    return std::all_of(segment.begin(), segment.end(), [](char c) { return c >= '0' && c <= '9'; });
  }
  return std::all_of(segment.begin(), segment.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           c == '_' || c == '-';
  });
}

bool IsParam(std::string_view segment) {
  return segment.size() > 2 && segment.front() == '{' && segment.back() == '}';
}

}  // namespace

std::int64_t RequestContext::Id(std::string_view name) const {
  auto it = path.find(name);
  assert(it != path.end());
  return std::stoll(it->second);
}

std::optional<std::string> RequestContext::Query(const std::string& name) const {
  if (!req.has_param(name)) return std::nullopt;
  return req.get_param_value(name);
}

std::optional<std::vector<std::string_view>> SplitPath(std::string_view path) {
  if (path.empty() || path.front() != '/') return std::nullopt;
  std::vector<std::string_view> segments;
  std::size_t start = 1;
  while (start <= path.size()) {
    std::size_t end = path.find('/', start);
    if (end == std::string_view::npos) end = path.size();
    std::string_view segment = path.substr(start, end - start);
    if (segment.empty() || segment == "." || segment == "..") return std::nullopt;
    segments.push_back(segment);
    start = end + 1;
  }
  return segments;
}

void RouteTable::Add(Route route) {
  auto segments = SplitPath(route.path);
  assert(segments.has_value());
  Compiled compiled;
  for (auto s : *segments) compiled.segments.emplace_back(s);
  for (const auto& r : routes_) {
    assert(!(r.method == route.method && r.path == route.path) && "duplicate route");
    (void)r;
  }
  routes_.push_back(std::move(route));
  compiled_.push_back(std::move(compiled));
}

RouteMatch RouteTable::Match(std::string_view method, std::string_view path) const {
  RouteMatch match;
  auto segments = SplitPath(path);
  if (!segments) return match;
  for (std::size_t i = 0; i < routes_.size(); ++i) {
    const auto& templ = compiled_[i].segments;
    if (templ.size() != segments->size()) continue;
    std::map<std::string, std::string, std::less<>> params;
    bool ok = true;
    for (std::size_t k = 0; k < templ.size() && ok; ++k) {
      const std::string& t = templ[k];
      if (IsParam(t)) {
        std::string_view name = std::string_view(t).substr(1, t.size() - 2);
        ok = MatchesParam(name, (*segments)[k]);
        if (ok) params.emplace(std::string(name), std::string((*segments)[k]));
      } else {
        ok = t == (*segments)[k];
      }
    }
    if (!ok) continue;
    const bool method_ok = routes_[i].method == method ||
                           (method == "HEAD" && routes_[i].method == "GET");
    if (method_ok && !match.route) {
      match.route = &routes_[i];
      match.path = std::move(params);
    }
    match.allowed_methods.push_back(routes_[i].method);
  }
  return match;
}

}  // namespace fesbench::server::http
