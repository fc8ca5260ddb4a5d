#include "server/http/auth.h"

namespace fesbench::server::http {

namespace {
const api::Status kBadToken{api::ErrorCode::kUnauthenticated,
                            "a valid bearer token is required (Authorization: Bearer <token>)"};
}  // namespace

Authenticator::Authenticator(storage::Database& db, std::chrono::milliseconds cache_ttl,
                             std::size_t cache_capacity)
    : users_(db), ttl_(cache_ttl), capacity_(cache_capacity) {}

api::Result<storage::User> Authenticator::Authenticate(std::string_view header) {
  constexpr std::string_view kScheme = "Bearer ";
  if (header.size() <= kScheme.size() || header.substr(0, kScheme.size()) != kScheme ||
      header.size() > 256) {
    return kBadToken;
  }
  const std::string token(header.substr(kScheme.size()));
  const auto now = std::chrono::steady_clock::now();
  {
    std::lock_guard lock(mu_);
    auto it = cache_.find(token);
    if (it != cache_.end() && it->second.expires > now) return it->second.user;
  }
  auto user = users_.Authenticate(token);
  if (!user.ok()) {
    if (user.status().code() == api::ErrorCode::kUnauthenticated) return kBadToken;
    return user.status();
  }
  std::lock_guard lock(mu_);
  if (cache_.size() >= capacity_) cache_.clear();
  cache_[token] = Entry{*user, now + ttl_};
  return user;
}

api::Status Authenticator::Authorise(const storage::User& user, RoleMask allowed) {
  if (allowed & RoleBit(user.role)) return api::Status::Ok();
  return {api::ErrorCode::kPermissionDenied,
          "role " + std::string(storage::RoleName(user.role)) + " may not do this (allowed: " +
              RoleList(allowed) + ")"};
}

void Authenticator::Invalidate() {
  std::lock_guard lock(mu_);
  cache_.clear();
}

std::string RoleList(RoleMask mask) {
  std::string out;
  for (auto role : {storage::Role::kClinician, storage::Role::kAnalyst, storage::Role::kAdmin}) {
    if (!(mask & RoleBit(role))) continue;
    if (!out.empty()) out += ", ";
    out += storage::RoleName(role);
  }
  return out;
}

}  // namespace fesbench::server::http
