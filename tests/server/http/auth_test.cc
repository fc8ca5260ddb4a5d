// The Authenticator's gate (docs/SAFETY.md, "Sign-in failures") on a temporary database with a
// hand-driven clock: failed sign-ins (401) and role refusals (403, any
// method) are audited without the token; a burst of failed tokens from one
// address is slowed down (429 with Retry-After, audited once per burst)
// while other addresses and valid tokens from the same address are not; the
// bucket refills with time.
#include "server/http/auth.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <filesystem>

#include "storage/audit_log.h"
#include "tests/support/manual_clock.h"

namespace fesbench::server::http {
namespace {

using namespace std::chrono_literals;

struct AuthRig {
  AuthRig() {
    static std::atomic<int> counter{0};
    dir = std::filesystem::temp_directory_path() /
          ("fesbench_auth_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    std::filesystem::create_directories(dir);
    storage::DatabaseOptions o;
    o.path = (dir / "fesbench.db").string();
    o.synchronous = storage::Synchronous::kNormal;
    db = std::move(storage::Database::Open(o)).value();
    storage::UserRepository users(*db);
    auto analyst = users.CreateUser("ana", storage::Role::kAnalyst);
    analyst_token = "Bearer " + users.IssueToken(analyst->id, "t")->token;
    auto clinician = users.CreateUser("cli", storage::Role::kClinician);
    clinician_token = "Bearer " + users.IssueToken(clinician->id, "t")->token;
    AuthenticatorOptions options;
    options.failed_tokens.burst = 3;
    options.failed_tokens.refill_per_s = 0.5;
    options.clock = &clock;
    auth = std::make_unique<Authenticator>(*db, options);
  }
  ~AuthRig() {
    auth.reset();
    db.reset();
    std::filesystem::remove_all(dir);
  }
  std::vector<storage::AuditEntry> Audit() {
    auto entries = storage::AuditLog(*db).List({});
    EXPECT_TRUE(entries.ok());
    std::vector<storage::AuditEntry> out = *entries;
    std::reverse(out.begin(), out.end());  // oldest first
    return out;
  }
  Admission Try(const std::string& header, const std::string& address = "10.0.0.7",
                Permission permission = Permission::kRead) {
    return auth->Admit(header, address, permission, "GET /api/v1/subjects", "/api/v1/subjects");
  }

  std::filesystem::path dir;
  std::unique_ptr<storage::Database> db;
  std::string analyst_token;
  std::string clinician_token;  ///< never presented before the burst: not cached.
  ::fesbench::testing::ManualClock clock;
  std::unique_ptr<Authenticator> auth;
};

const std::string kWrong = "Bearer fsb_" + std::string(64, '0');

TEST(Authenticator, FailedSignInsAndRoleRefusalsAreAuditedWithoutTheToken) {
  AuthRig rig;
  Admission bad = rig.Try(kWrong);
  EXPECT_FALSE(bad.user);
  EXPECT_EQ(bad.status.code(), api::ErrorCode::kUnauthenticated);
  EXPECT_EQ(bad.retry_after_s, 0);
  Admission denied = rig.auth->Admit(rig.analyst_token, "10.0.0.7", Permission::kAdminister,
                                     "GET /api/v1/audit", "/api/v1/audit");
  EXPECT_EQ(denied.status.code(), api::ErrorCode::kPermissionDenied);
  EXPECT_EQ(denied.status.message(), "role analyst may not do this (allowed: admin)");
  Admission ok = rig.Try(rig.analyst_token);
  ASSERT_TRUE(ok.user);
  EXPECT_EQ(ok.user->name, "ana");
  Admission anonymous = rig.Try("");
  EXPECT_EQ(anonymous.status.code(), api::ErrorCode::kUnauthenticated);

  const auto audit = rig.Audit();
  ASSERT_EQ(audit.size(), 2u) << "the 401 and the 403; not the success nor the anonymous call";
  EXPECT_EQ(audit[0].entry.actor, "10.0.0.7");
  EXPECT_FALSE(audit[0].entry.user_id.has_value());
  EXPECT_EQ(audit[0].entry.action, "GET /api/v1/subjects");
  EXPECT_EQ(audit[0].entry.outcome, "401 unauthenticated");
  EXPECT_EQ(audit[0].entry.request_summary.find("fsb_"), std::string::npos) << "never the token";
  EXPECT_EQ(audit[1].entry.actor, "ana");
  EXPECT_TRUE(audit[1].entry.user_id.has_value());
  EXPECT_EQ(audit[1].entry.action, "GET /api/v1/audit");
  EXPECT_EQ(audit[1].entry.outcome, "403 permission_denied");
}

TEST(Authenticator, ABurstOfFailedTokensFromOneAddressIsSlowedDown) {
  AuthRig rig;
  ASSERT_TRUE(rig.Try(rig.analyst_token).user);  // signed in a moment ago: cached
  for (int k = 0; k < 3; ++k) {
    Admission a = rig.Try(kWrong);
    EXPECT_EQ(a.retry_after_s, 0) << k;
    EXPECT_EQ(a.status.code(), api::ErrorCode::kUnauthenticated);
  }
  // The bucket (3) is empty: 429, 2 s until one failure is regained at 0.5/s.
  Admission slowed = rig.Try(kWrong);
  EXPECT_FALSE(slowed.user);
  EXPECT_EQ(slowed.retry_after_s, 2);
  // A valid token is looked up and admitted whatever the address's failures:
  // one never checked before (not cached) as well as a recent one. Only
  // wrong tokens are slowed down.
  Admission valid_uncached = rig.Try(rig.clinician_token);
  EXPECT_TRUE(valid_uncached.user);
  EXPECT_EQ(valid_uncached.retry_after_s, 0);
  EXPECT_TRUE(rig.Try(rig.analyst_token).user);
  EXPECT_EQ(rig.Try("Bearer fsb_" + std::string(64, '1')).retry_after_s, 2);
  EXPECT_EQ(rig.Try(kWrong, "10.0.0.8").retry_after_s, 0);

  auto audit = rig.Audit();
  EXPECT_EQ(std::count_if(audit.begin(), audit.end(),
                          [](const auto& e) { return e.entry.outcome == "429 too_many_requests"; }),
            1)
      << "one row per burst, not per request";
  EXPECT_EQ(std::count_if(audit.begin(), audit.end(),
                          [](const auto& e) {
                            return e.entry.outcome == "401 unauthenticated" &&
                                   e.entry.actor == "10.0.0.7";
                          }),
            3);

  // Time refills the bucket: one failure per 2 s.
  rig.clock.Advance(1);
  EXPECT_EQ(rig.Try(kWrong).retry_after_s, 1);
  rig.clock.Advance(1);
  EXPECT_EQ(rig.Try(kWrong).retry_after_s, 0);
  EXPECT_EQ(rig.Try(kWrong).retry_after_s, 2);
  rig.clock.Advance(10);  // the token's cache entry has expired by now
  ASSERT_TRUE(rig.Try(rig.analyst_token).user) << "a full bucket checks tokens again";
}

}  // namespace
}  // namespace fesbench::server::http
