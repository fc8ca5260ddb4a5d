#pragma once

/// @file
/// Users, roles and tokens on the wire (docs/API.md, "HTTP conventions",
/// users, tokens, `me`). Storage keeps users as this type
/// (storage/users.h). Readers as api/subject.h.

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>

#include "api/clock.h"
#include "api/status.h"

namespace fesbench::api {

enum class Role { kClinician, kAnalyst, kAdmin };
/// "clinician", "analyst", "admin".
std::string_view RoleName(Role role);
std::optional<Role> ParseRole(std::string_view name);

struct User {
  std::int64_t id = 0;
  std::string name;
  Role role = Role::kAnalyst;
  UtcTime created_at;
  bool active = true;  ///< false once deactivated.
  friend bool operator==(const User&, const User&) = default;
};
/// {"id", "name", "role", "active", "created_at_utc"}.
nlohmann::json UserToJson(const User& user);
/// GET /me sends only {"id", "name", "role"}: the others keep their defaults.
Result<User> UserFromJson(const nlohmann::json& json);
/// GET /me: {"id", "name", "role"}.
nlohmann::json SignedInUserToJson(const User& user);

/// A token's metadata (GET /tokens; the secret is never shown again). Times
/// are ISO-8601 UTC text as stored.
struct TokenInfo {
  std::int64_t id = 0;
  std::int64_t user_id = 0;
  std::string user_name;
  std::string label;
  std::string created_at_utc;
  std::optional<std::string> expires_at_utc;
  std::optional<std::string> revoked_at_utc;  ///< revoked when set.
  friend bool operator==(const TokenInfo&, const TokenInfo&) = default;
};
/// {"id", "user_id", "user_name", "label", "created_at_utc",
///  "expires_at_utc", "revoked", "revoked_at_utc"} (absent times null).
nlohmann::json TokenInfoToJson(const TokenInfo& token);
Result<TokenInfo> TokenInfoFromJson(const nlohmann::json& json);

/// A newly issued token (POST /tokens): `token` is the only copy of the secret.
struct IssuedTokenView {
  std::int64_t id = 0;
  std::int64_t user_id = 0;
  std::string label;
  std::string token;
  std::optional<UtcTime> expires_at;
  friend bool operator==(const IssuedTokenView&, const IssuedTokenView&) = default;
};
/// {"id", "user_id", "label", "token", "expires_at_utc" (null: never)}.
nlohmann::json IssuedTokenToJson(const IssuedTokenView& token);
Result<IssuedTokenView> IssuedTokenFromJson(const nlohmann::json& json);

/// POST /users: {"name", "role"} (the server's strict reader is
/// server/http/resources_json.h).
struct NewUserRequest {
  std::string name;
  Role role = Role::kAnalyst;
};
nlohmann::json NewUserRequestToJson(const NewUserRequest& request);

/// POST /tokens: {"user_id", "label"?, "expires_in_s"?} (expiry 60 s – 10
/// years; an empty label is not written).
struct NewTokenRequest {
  std::int64_t user_id = 0;
  std::string label;
  std::optional<std::int64_t> expires_in_s;
};
nlohmann::json NewTokenRequestToJson(const NewTokenRequest& request);

}  // namespace fesbench::api
