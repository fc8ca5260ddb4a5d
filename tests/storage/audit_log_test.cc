#include "storage/audit_log.h"

#include <gtest/gtest.h>

#include "storage/users.h"
#include "storage_test_util.h"

namespace fesbench::storage {
namespace {

using testing::Epoch2026;
using testing::StorageTest;

TEST_P(StorageTest, AuditLogAppendsAndFilters) {
  auto user = UserRepository(*db_).CreateUser("erin", Role::kAdmin);  // clock tick 0
  ASSERT_TRUE(user.ok());
  AuditLog log(*db_);
  for (int i = 0; i < 5; ++i) {  // clock ticks 1..5
    auto id = log.Append({i % 2 == 0 ? std::optional<std::int64_t>(user->id) : std::nullopt,
                          i % 2 == 0 ? "erin" : "system", "POST /api/v1/backup",
                          "backup/" + std::to_string(i), "{}", "202"});
    ASSERT_TRUE(id.ok()) << id.status().ToString();
  }
  auto all = log.List({});
  ASSERT_TRUE(all.ok()) << all.status().ToString();
  ASSERT_EQ(all->size(), 5u);
  EXPECT_EQ(all->front().entry.target, "backup/4");  // newest first
  EXPECT_EQ(api::FormatUtc(all->back().at), "2026-01-01T00:00:01.000000Z");
  auto by_user = log.List({std::nullopt, std::nullopt, user->id, 100, std::nullopt});
  ASSERT_TRUE(by_user.ok());
  EXPECT_EQ(by_user->size(), 3u);
  auto window = log.List({Epoch2026() + std::chrono::seconds(2),
                          Epoch2026() + std::chrono::seconds(4), std::nullopt, 100, std::nullopt});
  ASSERT_TRUE(window.ok());
  ASSERT_EQ(window->size(), 2u);
  EXPECT_EQ(window->front().entry.target, "backup/2");

  // Keyset pages, newest first: each page starts below the last id shown.
  std::vector<std::string> walked;
  AuditQuery page;
  page.limit = 2;
  for (int n = 0; n < 5; ++n) {
    auto rows = log.List(page);
    ASSERT_TRUE(rows.ok());
    if (rows->empty()) break;
    for (const auto& e : *rows) walked.push_back(e.entry.target);
    page.before_id = rows->back().id;
  }
  EXPECT_EQ(walked, (std::vector<std::string>{"backup/4", "backup/3", "backup/2", "backup/1",
                                              "backup/0"}));
  page = AuditQuery{};
  page.user_id = user->id;
  page.before_id = all->front().id;  // below backup/4: erin's backup/2 and backup/0
  auto older = log.List(page);
  ASSERT_TRUE(older.ok());
  ASSERT_EQ(older->size(), 2u);
  EXPECT_EQ(older->front().entry.target, "backup/2");

  // Each page is an index range however deep: no scan, no sort.
  ExpectIndexRange("SELECT id FROM audit_log WHERE id < ?1 ORDER BY id DESC LIMIT ?2", "",
                   "audit_log");
  ExpectIndexRange(
      "SELECT id FROM audit_log WHERE user_id = ?1 AND id < ?2 ORDER BY id DESC LIMIT ?3",
      "audit_log_user_id");

  EXPECT_EQ(log.Append({std::nullopt, "x", "", "", "", ""}).status().field(), "action");
  EXPECT_EQ(log.Append({999, "x", "GET", "", "", ""}).status().message(), "user 999 not found");
}

}  // namespace
}  // namespace fesbench::storage
