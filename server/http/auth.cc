#include "server/http/auth.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <vector>

#include "storage/audit_log.h"

namespace fesbench::server::http {

namespace {
const api::Status kBadToken{api::ErrorCode::kUnauthenticated,
                            "a valid bearer token is required (Authorization: Bearer <token>)"};
constexpr std::string_view kScheme = "Bearer ";

bool WellFormed(std::string_view header) {
  return header.size() > kScheme.size() && header.substr(0, kScheme.size()) == kScheme &&
         header.size() <= 256;
}
}  // namespace

Authenticator::Authenticator(storage::Database& db, AuthenticatorOptions options)
    : db_(db), users_(db), options_(std::move(options)) {
  if (options_.clock == nullptr) options_.clock = api::Clock::Real();
  options_.failed_tokens.burst = std::max(1.0, options_.failed_tokens.burst);
  if (!(options_.failed_tokens.refill_per_s > 0.0)) options_.failed_tokens.refill_per_s = 1.0;
}

std::chrono::steady_clock::time_point Authenticator::Now() const {
  return std::chrono::steady_clock::time_point(
      std::chrono::duration_cast<std::chrono::steady_clock::duration>(
          std::chrono::duration<double>(options_.clock->MonotonicSeconds())));
}

std::optional<storage::User> Authenticator::Cached(const std::string& token) {
  std::lock_guard lock(mu_);
  auto it = cache_.find(token);
  if (it != cache_.end() && it->second.expires > Now()) return it->second.user;
  return std::nullopt;
}

api::Result<storage::User> Authenticator::Authenticate(std::string_view header) {
  if (!WellFormed(header)) return kBadToken;
  const std::string token(header.substr(kScheme.size()));
  if (auto cached = Cached(token)) return *cached;
  auto user = users_.Authenticate(token);
  if (!user.ok()) {
    if (user.status().code() == api::ErrorCode::kUnauthenticated) return kBadToken;
    return user.status();
  }
  std::lock_guard lock(mu_);
  if (cache_.size() >= options_.cache_capacity) cache_.clear();
  cache_[token] = Entry{*user, Now() + options_.cache_ttl};
  return user;
}

int Authenticator::WaitFor(const std::string& address, bool* first_refusal) {
  const FailedTokenLimits& l = options_.failed_tokens;
  const auto now = Now();
  std::lock_guard lock(mu_);
  auto it = buckets_.find(address);
  if (it == buckets_.end()) return 0;  // a full bucket
  Bucket& b = it->second;
  const double elapsed_s = std::chrono::duration<double>(now - b.at).count();
  b.tokens = std::min(l.burst, b.tokens + std::max(0.0, elapsed_s) * l.refill_per_s);
  b.at = now;
  if (b.tokens >= 1.0) {
    b.throttle_audited = false;
    return 0;
  }
  *first_refusal = !b.throttle_audited;
  b.throttle_audited = true;
  return std::max(1, static_cast<int>(std::ceil((1.0 - b.tokens) / l.refill_per_s)));
}

void Authenticator::TakeFailure(const std::string& address) {
  const FailedTokenLimits& l = options_.failed_tokens;
  const auto now = Now();
  std::lock_guard lock(mu_);
  auto it = buckets_.find(address);
  if (it == buckets_.end()) {
    if (buckets_.size() >= l.max_addresses) {
      // Forget the addresses closest to a full bucket (the least suspicious).
      std::vector<std::pair<double, std::string>> fullness;
      fullness.reserve(buckets_.size());
      for (const auto& [a, b] : buckets_) {
        const double elapsed_s = std::chrono::duration<double>(now - b.at).count();
        fullness.emplace_back(b.tokens + elapsed_s * l.refill_per_s, a);
      }
      std::sort(fullness.begin(), fullness.end(), std::greater<>());
      for (std::size_t k = 0; k < fullness.size() / 2 + 1; ++k) buckets_.erase(fullness[k].second);
    }
    it = buckets_.emplace(address, Bucket{l.burst, now, false}).first;
  }
  it->second.tokens = std::max(0.0, it->second.tokens - 1.0);
}

void Authenticator::AuditEntry(std::optional<std::int64_t> user_id, std::string actor,
                               std::string_view action, std::string_view target,
                               std::string summary, std::string outcome) {
  storage::NewAuditEntry e;
  e.user_id = user_id;
  e.actor = std::move(actor);
  e.action = std::string(action);
  e.target = std::string(target);
  e.request_summary = std::move(summary);
  e.outcome = std::move(outcome);
  auto appended = storage::AuditLog(db_).Append(e);
  if (!appended.ok()) {
    std::cerr << "fesbench-server: audit log: " << appended.status().ToString() << std::endl;
  }
}

Admission Authenticator::Admit(std::string_view header, std::string_view address,
                               Permission permission, std::string_view action,
                               std::string_view target) {
  Admission out;
  const std::string who = address.empty() ? std::string("unknown address")
                                          : std::string(address.substr(0, 64));
  if (header.empty()) {
    out.status = kBadToken;  // no sign-in attempted: neither audited nor counted
    return out;
  }
  // A valid token is looked up first: the failed-token throttle slows only
  // requests whose token is wrong, never a user behind somebody else's
  // failures (an e-stop from the same address among them).
  auto user = Authenticate(header);
  if (!user.ok()) {
    out.status = user.status();
    if (out.status.code() != api::ErrorCode::kUnauthenticated) return out;
    bool first_refusal = false;
    if (const int wait_s = WaitFor(who, &first_refusal); wait_s > 0) {
      out.retry_after_s = wait_s;
      out.status = api::Status(api::ErrorCode::kUnauthenticated,
                               "too many failed tokens from " + who + ": retry in " +
                                   std::to_string(wait_s) + " s");
      if (first_refusal) {
        AuditEntry(std::nullopt, who, action, target,
                   "a burst of failed tokens: slowed down (" +
                       std::to_string(static_cast<int>(options_.failed_tokens.burst)) +
                       " failures, then " + std::to_string(options_.failed_tokens.refill_per_s) +
                       " per second)",
                   "429 too_many_requests");
      }
      return out;
    }
    TakeFailure(who);
    AuditEntry(std::nullopt, who, action, target,
               WellFormed(header) ? "unknown, revoked or expired bearer token"
                                  : "malformed Authorization header",
               "401 unauthenticated");
    return out;
  }
  if (api::Status st = Authorise(*user, permission); !st.ok()) {
    AuditEntry(user->id, user->name, action, target, "role " + std::string(storage::RoleName(user->role)),
               "403 permission_denied");
    out.status = st;
    return out;
  }
  out.user = std::move(*user);
  return out;
}

api::Status Authenticator::Authorise(const storage::User& user, Permission permission) {
  return services::Require(ActorOf(user), permission);
}

void Authenticator::Invalidate() {
  std::lock_guard lock(mu_);
  cache_.clear();
}

services::Actor ActorOf(const storage::User& user) { return {user.id, user.name, user.role}; }

}  // namespace fesbench::server::http
