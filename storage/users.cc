#include "storage/users.h"

#include <openssl/evp.h>
#include <openssl/rand.h>

#include <array>

#include "storage/row_helpers.h"

namespace fesbench::storage {
namespace {

constexpr std::string_view kUserSql =
    "SELECT u.id, u.name, u.role, u.created_at_utc,"
    " NOT EXISTS (SELECT 1 FROM user_deactivations d WHERE d.user_id = u.id) FROM users u ";

template <typename... Key>
api::Result<std::vector<User>> QueryUsers(Connection& c, std::string_view where,
                                          const Key&... key) {
  return internal::QueryRows(
      c, std::string(kUserSql) + std::string(where) + " ORDER BY u.id",
      [](const Statement& s) -> api::Result<User> {
        User user;
        user.id = s.Int64(0);
        user.name = s.Text(1);
        const auto role = ParseRole(s.Text(2));
        const auto created = api::ParseUtc(s.Text(3));
        if (!role || !created) return internal::BadStoredValue("user");
        user.role = *role;
        user.created_at = *created;
        user.active = s.Int64(4) != 0;
        return user;
      },
      key...);
}

api::Result<User> GetUserIn(Connection& c, std::int64_t id) {
  return internal::One(QueryUsers(c, "WHERE u.id = ?1", id), "user", id);
}

api::Result<std::string> NewTokenText() {
  std::array<unsigned char, 32> bytes{};
  if (RAND_bytes(bytes.data(), static_cast<int>(bytes.size())) != 1) {
    return api::Status::Internal("the system random generator failed");
  }
  static constexpr char kHex[] = "0123456789abcdef";
  std::string token = "fsb_";
  for (unsigned char b : bytes) {
    token += kHex[b >> 4];
    token += kHex[b & 0xf];
  }
  return token;
}

}  // namespace


std::vector<std::byte> Sha256(std::string_view text) {
  std::vector<std::byte> digest(32);
  unsigned int size = 0;
  EVP_Digest(text.data(), text.size(), reinterpret_cast<unsigned char*>(digest.data()), &size,
             EVP_sha256(), nullptr);
  digest.resize(size);
  return digest;
}

api::Result<User> UserRepository::CreateUser(std::string_view name, Role role) {
  if (name.empty() || name.size() > 64) {
    return api::Status::InvalidArgument("user name must have 1 to 64 characters", "name");
  }
  return db_.Write([&](Connection& c) -> api::Result<User> {
    auto existing = internal::RowExists(c, "SELECT 1 FROM users WHERE name = ?1", name);
    if (!existing.ok()) return existing.status();
    if (*existing) {
      return api::Status::AlreadyExists("user '" + std::string(name) + "' already exists", "name");
    }
    auto id =
        internal::InsertRow(c, "INSERT INTO users (name, role, created_at_utc) VALUES (?1, ?2, ?3)",
                            name, RoleName(role), api::FormatUtc(db_.Now()));
    if (!id.ok()) return id.status();
    return GetUserIn(c, *id);
  });
}

api::Result<User> UserRepository::GetUser(std::int64_t user_id) {
  return db_.Read([&](Connection& c) { return GetUserIn(c, user_id); });
}

api::Result<User> UserRepository::GetUserByName(std::string_view name) {
  return db_.Read([&](Connection& c) -> api::Result<User> {
    auto users = QueryUsers(c, "WHERE u.name = ?1", name);
    if (!users.ok()) return users.status();
    if (users->empty()) return api::Status::NotFound("user '" + std::string(name) + "' not found");
    return std::move(users->front());
  });
}

api::Result<std::vector<User>> UserRepository::ListUsers() {
  return db_.Read([&](Connection& c) { return QueryUsers(c, ""); });
}

api::Status UserRepository::DeactivateUser(std::int64_t user_id, std::string_view reason) {
  return db_.Write([&](Connection& c) -> api::Status {
    auto user = GetUserIn(c, user_id);
    if (!user.ok()) return user.status();
    if (!user->active) {
      return api::Status::FailedPrecondition("user " + std::to_string(user_id) +
                                             " is already deactivated");
    }
    return internal::Execute(
        c, "INSERT INTO user_deactivations (user_id, reason, at_utc) VALUES (?1, ?2, ?3)", user_id,
        reason, api::FormatUtc(db_.Now()));
  });
}

api::Result<IssuedToken> UserRepository::IssueToken(std::int64_t user_id, std::string_view label,
                                                    std::optional<api::UtcTime> expires_at) {
  // The secret is drawn once, outside the transaction (which may be retried).
  auto token = NewTokenText();
  if (!token.ok()) return token.status();
  const std::vector<std::byte> digest = Sha256(*token);
  return db_.Write([&](Connection& c) -> api::Result<IssuedToken> {
    auto user = GetUserIn(c, user_id);
    if (!user.ok()) return user.status();
    if (!user->active) {
      return api::Status::FailedPrecondition("user " + std::to_string(user_id) + " is deactivated");
    }
    std::optional<std::string> expires;
    if (expires_at) expires = api::FormatUtc(*expires_at);
    auto id = internal::InsertRow(
        c,
        "INSERT INTO tokens (user_id, token_sha256, label, created_at_utc, expires_at_utc)"
        " VALUES (?1, ?2, ?3, ?4, ?5)",
        user_id, digest, label, api::FormatUtc(db_.Now()), expires);
    if (!id.ok()) return id.status();
    return IssuedToken{*id, *token, expires_at};
  });
}

api::Result<User> UserRepository::Authenticate(std::string_view token) {
  const std::vector<std::byte> digest = Sha256(token);
  const std::string now = api::FormatUtc(db_.Now());
  return db_.Read([&](Connection& c) -> api::Result<User> {
    auto statement = c.Prepare(
        "SELECT t.user_id FROM tokens t WHERE t.token_sha256 = ?1"
        " AND (t.expires_at_utc IS NULL OR t.expires_at_utc > ?2)"
        " AND NOT EXISTS (SELECT 1 FROM token_revocations r WHERE r.token_id = t.id)"
        " AND NOT EXISTS (SELECT 1 FROM user_deactivations d WHERE d.user_id = t.user_id)");
    if (!statement.ok()) return statement.status();
    statement->BindBlob(1, digest).Bind(2, now);
    auto row = statement->Step();
    if (!row.ok()) return row.status();
    if (!*row) return api::Status(api::ErrorCode::kUnauthenticated, "invalid or expired token");
    const std::int64_t user_id = statement->Int64(0);
    return GetUserIn(c, user_id);
  });
}

api::Status UserRepository::RevokeToken(std::int64_t token_id) {
  return db_.Write([&](Connection& c) -> api::Status {
    if (auto s = internal::RequireRow(c, "SELECT 1 FROM tokens WHERE id = ?1", token_id, "token");
        !s.ok()) {
      return s;
    }
    auto revoked =
        internal::RowExists(c, "SELECT 1 FROM token_revocations WHERE token_id = ?1", token_id);
    if (!revoked.ok()) return revoked.status();
    if (*revoked) {
      return api::Status::FailedPrecondition("token " + std::to_string(token_id) +
                                             " is already revoked");
    }
    return internal::Execute(c, "INSERT INTO token_revocations (token_id, at_utc) VALUES (?1, ?2)",
                             token_id, api::FormatUtc(db_.Now()));
  });
}

}  // namespace fesbench::storage
