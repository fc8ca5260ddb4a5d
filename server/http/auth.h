#pragma once

/// @file
/// Bearer-token authentication and role checks (DESIGN.md §8). Tokens are
/// checked against storage (SHA-256 digests, storage/users.h); recent
/// answers are cached for `cache_ttl` so a busy client does not cost a
/// database read per request. Revoking a token or deactivating a user
/// through the server calls Invalidate(), so the change is effective at
/// once; a change made behind the server's back takes up to cache_ttl.

#include <chrono>
#include <cstddef>
#include <mutex>
#include <string>
#include <string_view>
#include <unordered_map>

#include "api/status.h"
#include "storage/users.h"

namespace fesbench::server::http {

/// A set of roles as bits (1 << Role).
using RoleMask = unsigned;
constexpr RoleMask RoleBit(storage::Role role) { return 1u << static_cast<unsigned>(role); }
inline constexpr RoleMask kClinician = RoleBit(storage::Role::kClinician);
inline constexpr RoleMask kAnalyst = RoleBit(storage::Role::kAnalyst);
inline constexpr RoleMask kAdmin = RoleBit(storage::Role::kAdmin);
inline constexpr RoleMask kAnyRole = kClinician | kAnalyst | kAdmin;

class Authenticator {
 public:
  explicit Authenticator(storage::Database& db,
                         std::chrono::milliseconds cache_ttl = std::chrono::seconds(2),
                         std::size_t cache_capacity = 4096);

  /// The user behind an `Authorization` header value ("Bearer fsb_…").
  /// kUnauthenticated (one message for every reason) when the header is
  /// missing, malformed, or names an unknown, revoked or expired token.
  api::Result<storage::User> Authenticate(std::string_view authorization_header);
  /// kPermissionDenied naming the roles allowed, unless user's role is in
  /// `allowed`.
  static api::Status Authorise(const storage::User& user, RoleMask allowed);
  /// Drops every cached answer.
  void Invalidate();

 private:
  struct Entry {
    storage::User user;
    std::chrono::steady_clock::time_point expires;
  };
  storage::UserRepository users_;
  std::chrono::milliseconds ttl_;
  std::size_t capacity_;
  std::mutex mu_;
  std::unordered_map<std::string, Entry> cache_;
};

/// "clinician, admin" for a mask.
std::string RoleList(RoleMask mask);

}  // namespace fesbench::server::http
