#include "storage/users.h"

#include <gtest/gtest.h>

#include <set>

#include "storage_test_util.h"

namespace fesbench::storage {
namespace {

using testing::Epoch2026;
using testing::StorageTest;

TEST(Sha256, KnownDigest) {
  // FIPS 180-2 test vector: SHA-256("abc").
  const auto digest = Sha256("abc");
  ASSERT_EQ(digest.size(), 32u);
  EXPECT_EQ(digest[0], std::byte{0xba});
  EXPECT_EQ(digest[1], std::byte{0x78});
  EXPECT_EQ(digest[31], std::byte{0xad});
}

TEST_P(StorageTest, TokensAreStoredHashedAndAuthenticate) {
  UserRepository users(*db_);
  auto alice = users.CreateUser("alice", Role::kClinician);
  ASSERT_TRUE(alice.ok());
  auto token = users.IssueToken(alice->id, "laptop");
  ASSERT_TRUE(token.ok()) << token.status().ToString();
  EXPECT_EQ(token->token.size(), 4u + 64u);
  EXPECT_EQ(token->token.substr(0, 4), "fsb_");

  // Only the digest is in the file.
  auto stored = db_->Read([](Connection& c) -> api::Result<std::string> {
    auto s = c.Prepare("SELECT token_sha256 FROM tokens");
    if (!s.ok()) return s.status();
    auto row = s->Step();
    if (!row.ok()) return row.status();
    auto blob = s->Blob(0);
    return std::string(reinterpret_cast<const char*>(blob.data()), blob.size());
  });
  ASSERT_TRUE(stored.ok());
  const auto digest = Sha256(token->token);
  EXPECT_EQ(*stored, std::string(reinterpret_cast<const char*>(digest.data()), digest.size()));

  auto who = users.Authenticate(token->token);
  ASSERT_TRUE(who.ok());
  EXPECT_EQ(who->name, "alice");
  EXPECT_EQ(who->role, Role::kClinician);
  EXPECT_EQ(users.Authenticate("fsb_wrong").status().code(), api::ErrorCode::kUnauthenticated);

  // Two tokens are never equal (CSPRNG).
  std::set<std::string> seen{token->token};
  for (int i = 0; i < 5; ++i) {
    auto more = users.IssueToken(alice->id, "extra");
    ASSERT_TRUE(more.ok());
    EXPECT_TRUE(seen.insert(more->token).second);
  }

  ASSERT_TRUE(users.RevokeToken(token->token_id).ok());
  EXPECT_EQ(users.Authenticate(token->token).status().code(), api::ErrorCode::kUnauthenticated);
  EXPECT_EQ(users.RevokeToken(token->token_id).code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_EQ(users.RevokeToken(999).code(), api::ErrorCode::kNotFound);
}

TEST_P(StorageTest, ExpiredTokensAndDeactivatedUsersAreRefused) {
  UserRepository users(*db_);
  auto bob = users.CreateUser("bob", Role::kAnalyst);
  ASSERT_TRUE(bob.ok());
  // The stepping clock is at 2026-01-01 plus a few seconds.
  auto expired = users.IssueToken(bob->id, "old", Epoch2026());
  auto valid = users.IssueToken(bob->id, "new", Epoch2026() + std::chrono::hours(1));
  ASSERT_TRUE(expired.ok() && valid.ok());
  EXPECT_EQ(users.Authenticate(expired->token).status().code(), api::ErrorCode::kUnauthenticated);
  EXPECT_TRUE(users.Authenticate(valid->token).ok());
  ASSERT_TRUE(users.DeactivateUser(bob->id, "left the lab").ok());
  EXPECT_EQ(users.Authenticate(valid->token).status().code(), api::ErrorCode::kUnauthenticated);
  EXPECT_EQ(users.DeactivateUser(bob->id, "again").code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_EQ(users.IssueToken(bob->id, "x").status().code(), api::ErrorCode::kFailedPrecondition);
  auto got = users.GetUser(bob->id);
  ASSERT_TRUE(got.ok());
  EXPECT_FALSE(got->active);
}

TEST_P(StorageTest, UserBadInputNamesTheProblem) {
  UserRepository users(*db_);
  ASSERT_TRUE(users.CreateUser("carol", Role::kAdmin).ok());
  auto duplicate = users.CreateUser("carol", Role::kAnalyst);
  EXPECT_EQ(duplicate.status().code(), api::ErrorCode::kAlreadyExists);
  EXPECT_EQ(duplicate.status().field(), "name");
  EXPECT_EQ(users.CreateUser("", Role::kAnalyst).status().field(), "name");
  EXPECT_EQ(users.GetUser(77).status().message(), "user 77 not found");
  EXPECT_EQ(users.GetUserByName("dave").status().code(), api::ErrorCode::kNotFound);
  EXPECT_EQ(users.IssueToken(77, "x").status().code(), api::ErrorCode::kNotFound);
  auto list = users.ListUsers();
  ASSERT_TRUE(list.ok());
  ASSERT_EQ(list->size(), 1u);
  EXPECT_EQ(list->front().role, Role::kAdmin);
}

}  // namespace
}  // namespace fesbench::storage
