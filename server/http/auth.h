#pragma once

/// @file
/// Bearer-token authentication and role checks (docs/API.md, "HTTP conventions"). Tokens are
/// checked against storage (SHA-256 digests, storage/users.h); recent
/// answers are cached for `cache_ttl` so a busy client does not cost a
/// database read per request. Revoking a token or deactivating a user
/// through the server calls Invalidate(), so the change is effective at
/// once; a change made behind the server's back takes up to cache_ttl.
///
/// Admit() is the front end's one gate (docs/SAFETY.md, "Sign-in failures"): it audits every
/// failed sign-in (a presented token that is not valid: 401) and every
/// request refused for its role (403, any method), and slows down a burst
/// of failed tokens from one client address with a token bucket: while the
/// address's bucket is empty its requests with a wrong token get 429 with
/// Retry-After instead of 401 (and only the first is audited). A valid
/// token is always looked up first and admitted: the throttle never makes a
/// user wait for somebody else's failures. (Tokens carry 256 random bits,
/// storage/users.h, so the throttle guards the audit log and the database,
/// not the tokens' secrecy.)

#include <chrono>
#include <cstddef>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>

#include "api/clock.h"
#include "api/status.h"
#include "server/services/actor.h"
#include "storage/database.h"
#include "storage/users.h"

namespace fesbench::server::http {

/// What a route needs (server/services/actor.h: the one table of who may do what).
using services::Permission;

/// The per-address budget of failed tokens: a bucket of `burst` failures
/// that refills at `refill_per_s`.
struct FailedTokenLimits {
  double burst = 30.0;                ///< failed tokens an address may present at once, ≥ 1.
  double refill_per_s = 1.0;          ///< failures regained per second, > 0.
  std::size_t max_addresses = 10000;  ///< addresses tracked; the fullest buckets are dropped.
};

struct AuthenticatorOptions {
  std::chrono::milliseconds cache_ttl = std::chrono::seconds(2);
  std::size_t cache_capacity = 4096;
  FailedTokenLimits failed_tokens;
  /// Monotonic time of the cache and the rate limit; outlives the authenticator.
  api::Clock* clock = api::Clock::Real();
};

/// Admit's answer for one request.
struct Admission {
  std::optional<storage::User> user;  ///< set when admitted.
  api::Status status;                 ///< kUnauthenticated or kPermissionDenied otherwise.
  /// > 0 when the address is slowed down: answer 429 with Retry-After: this
  /// many seconds (status then says so).
  int retry_after_s = 0;
};

class Authenticator {
 public:
  explicit Authenticator(storage::Database& db, AuthenticatorOptions options = {});

  /// The user behind an `Authorization` header value ("Bearer fsb_…").
  /// kUnauthenticated (one message for every reason) when the header is
  /// missing, malformed, or names an unknown, revoked or expired token.
  api::Result<storage::User> Authenticate(std::string_view authorization_header);
  /// kPermissionDenied naming the roles allowed (services::Require), unless
  /// user's role has `permission`.
  static api::Status Authorise(const storage::User& user, Permission permission);

  /// Authenticates and authorises a request from client `address` for a
  /// route needing `permission`. `action` ("GET /api/v1/users") and `target`
  /// (the path) name it in the audit log. Audited: a presented token that
  /// fails (actor = the address, never the token), a role refusal (actor =
  /// the user), and the first request of a slowed-down burst. A request
  /// without an Authorization header is 401 but neither audited nor counted.
  Admission Admit(std::string_view authorization_header, std::string_view address,
                  Permission permission, std::string_view action, std::string_view target);

  /// Drops every cached answer.
  void Invalidate();

 private:
  struct Entry {
    storage::User user;
    std::chrono::steady_clock::time_point expires;
  };
  struct Bucket {
    double tokens = 0.0;
    std::chrono::steady_clock::time_point at;
    bool throttle_audited = false;  // this empty spell's audit row is written
  };
  std::chrono::steady_clock::time_point Now() const;
  std::optional<storage::User> Cached(const std::string& token);
  /// Refills the address's bucket; seconds until it holds one failure, 0 if it does.
  int WaitFor(const std::string& address, bool* first_refusal);
  void TakeFailure(const std::string& address);
  void AuditEntry(std::optional<std::int64_t> user_id, std::string actor, std::string_view action,
                  std::string_view target, std::string summary, std::string outcome);

  storage::Database& db_;
  storage::UserRepository users_;
  AuthenticatorOptions options_;
  std::mutex mu_;
  std::unordered_map<std::string, Entry> cache_;
  std::unordered_map<std::string, Bucket> buckets_;
};

/// The services' Actor (who acts, with which role) for an authenticated user.
services::Actor ActorOf(const storage::User& user);

}  // namespace fesbench::server::http
