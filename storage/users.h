#pragma once

/// @file
/// Users, roles and bearer tokens (docs/API.md, "HTTP conventions"). A token is 32 bytes from
/// OpenSSL's CSPRNG (RAND_bytes), handed out once as "fsb_" + 64 hex digits;
/// only its SHA-256 digest is stored. Deactivation and revocation are new
/// rows, never updates.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/status.h"
#include "api/user.h"
#include "storage/database.h"

namespace fesbench::storage {

// Roles and users are the wire's (api/user.h).
using api::ParseRole;
using api::Role;
using api::RoleName;
using api::User;

/// A newly issued token: `token` is the only copy of the secret.
struct IssuedToken {
  std::int64_t token_id = 0;
  std::string token;
  std::optional<api::UtcTime> expires_at;
};

/// SHA-256 of `text` (32 bytes).
std::vector<std::byte> Sha256(std::string_view text);

class UserRepository {
 public:
  explicit UserRepository(Database& db) : db_(db) {}

  /// kInvalidArgument (field "name") for an empty or over-long name (1–64),
  /// kAlreadyExists (field "name") when it is taken.
  api::Result<User> CreateUser(std::string_view name, Role role);
  api::Result<User> GetUser(std::int64_t user_id);
  api::Result<User> GetUserByName(std::string_view name);
  api::Result<std::vector<User>> ListUsers();
  /// kFailedPrecondition if already deactivated.
  api::Status DeactivateUser(std::int64_t user_id, std::string_view reason);

  /// Issues a token for an active user (kFailedPrecondition otherwise);
  /// `expires_at` nullopt never expires.
  api::Result<IssuedToken> IssueToken(std::int64_t user_id, std::string_view label,
                                      std::optional<api::UtcTime> expires_at = std::nullopt);
  /// The user a presented token belongs to. kUnauthenticated for an unknown,
  /// revoked or expired token or a deactivated user (one message for all,
  /// so a caller learns nothing about which).
  api::Result<User> Authenticate(std::string_view token);
  /// kNotFound for an unknown token id; kFailedPrecondition if revoked.
  api::Status RevokeToken(std::int64_t token_id);

 private:
  Database& db_;
};

}  // namespace fesbench::storage
