#include "storage/subjects.h"

#include <gtest/gtest.h>

#include <cmath>

#include "storage_test_util.h"

namespace fesbench::storage {
namespace {

using testing::StorageTest;

SubjectDetails Details() {
  SubjectDetails d;
  d.age_years = 27;
  d.sex = Sex::kMale;
  d.height_cm = 181.0;
  d.weight_kg = 77.5;
  d.shank_length_cm = 44.0;
  d.calf_circumference_cm = 37.5;
  return d;
}

TEST_P(StorageTest, SubjectCreateGetAndList) {
  SubjectRepository subjects(*db_);
  auto created = subjects.Create("K-001", Details());
  ASSERT_TRUE(created.ok()) << created.status().ToString();
  EXPECT_EQ(created->code, "K-001");
  EXPECT_EQ(created->current.revision, 1);
  EXPECT_EQ(created->current.details, Details());
  EXPECT_FALSE(created->current.corrects_id.has_value());
  EXPECT_EQ(api::FormatUtc(created->created_at), "2026-01-01T00:00:00.000000Z");

  auto by_id = subjects.Get(created->id);
  ASSERT_TRUE(by_id.ok());
  EXPECT_EQ(by_id->current.details.shank_length_cm, 44.0);
  auto by_code = subjects.GetByCode("K-001");
  ASSERT_TRUE(by_code.ok());
  EXPECT_EQ(by_code->id, created->id);
  ASSERT_TRUE(subjects.Create("K-002", SubjectDetails{}).ok());
  auto list = subjects.List();
  ASSERT_TRUE(list.ok());
  ASSERT_EQ(list->size(), 2u);
  EXPECT_EQ((*list)[1].code, "K-002");
  EXPECT_FALSE((*list)[1].current.details.height_cm.has_value());
}

TEST_P(StorageTest, SubjectCorrectionIsANewRevision) {
  SubjectRepository subjects(*db_);
  auto created = subjects.Create("K-003", Details());
  ASSERT_TRUE(created.ok());
  SubjectDetails fixed = Details();
  fixed.weight_kg = 75.0;
  auto corrected = subjects.Correct(created->id, fixed, "scale was miscalibrated");
  ASSERT_TRUE(corrected.ok()) << corrected.status().ToString();
  EXPECT_EQ(corrected->current.revision, 2);
  EXPECT_EQ(corrected->current.details.weight_kg, 75.0);
  EXPECT_EQ(corrected->current.corrects_id, created->current.id);
  auto revisions = subjects.Revisions(created->id);
  ASSERT_TRUE(revisions.ok());
  ASSERT_EQ(revisions->size(), 2u);
  EXPECT_EQ((*revisions)[0].details.weight_kg, 77.5);  // the original is kept
  EXPECT_EQ((*revisions)[1].reason, "scale was miscalibrated");
  EXPECT_EQ(subjects.Correct(created->id, fixed, "").status().field(), "reason");
}

TEST_P(StorageTest, SubjectBadInputNamesTheProblem) {
  SubjectRepository subjects(*db_);
  ASSERT_TRUE(subjects.Create("DUP", SubjectDetails{}).ok());
  auto duplicate = subjects.Create("DUP", SubjectDetails{});
  EXPECT_EQ(duplicate.status().code(), api::ErrorCode::kAlreadyExists);
  EXPECT_EQ(duplicate.status().field(), "code");
  EXPECT_NE(duplicate.status().message().find("DUP"), std::string::npos);

  EXPECT_EQ(subjects.Create("John Smith", SubjectDetails{}).status().field(), "code");
  EXPECT_EQ(subjects.Create("", SubjectDetails{}).status().field(), "code");
  SubjectDetails bad;
  bad.height_cm = -3;
  auto invalid = subjects.Create("OK", bad);
  EXPECT_EQ(invalid.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(invalid.status().field(), "height_cm");
  bad = {};
  bad.age_years = 200;
  EXPECT_EQ(subjects.Create("OK", bad).status().field(), "age_years");

  auto missing = subjects.Get(999);
  EXPECT_EQ(missing.status().code(), api::ErrorCode::kNotFound);
  EXPECT_EQ(missing.status().message(), "subject 999 not found");
  EXPECT_EQ(subjects.GetByCode("NOPE").status().code(), api::ErrorCode::kNotFound);
  EXPECT_EQ(subjects.Correct(999, SubjectDetails{}, "x").status().code(),
            api::ErrorCode::kNotFound);
  EXPECT_EQ(subjects.Revisions(999).status().code(), api::ErrorCode::kNotFound);
}

// A subject's range of motion (docs/SAFETY.md): both ends or neither, in
// a knee's range, at least 30° wide; kept by every revision.
TEST_P(StorageTest, SubjectRangeOfMotionIsStoredAndChecked) {
  SubjectRepository subjects(*db_);
  SubjectDetails d;
  d.rom_min_deg = -10.0;
  d.rom_max_deg = 135.5;
  auto created = subjects.Create("ROM-1", d);
  ASSERT_TRUE(created.ok()) << created.status().ToString();
  auto read = subjects.Get(created->id);
  ASSERT_TRUE(read.ok());
  EXPECT_EQ(read->current.details.rom_min_deg, -10.0);
  EXPECT_EQ(read->current.details.rom_max_deg, 135.5);
  SubjectDetails narrower = read->current.details;
  narrower.rom_max_deg = 95.0;
  ASSERT_TRUE(subjects.Correct(created->id, narrower, "measured again").ok());
  EXPECT_EQ(subjects.Get(created->id)->current.details.rom_max_deg, 95.0);

  const auto field = [&](std::optional<double> lo, std::optional<double> hi) {
    SubjectDetails bad;
    bad.rom_min_deg = lo;
    bad.rom_max_deg = hi;
    return subjects.Create("ROM-X", bad).status().field();
  };
  EXPECT_EQ(field(-10.0, std::nullopt), "rom_max_deg");  // one end alone
  EXPECT_EQ(field(std::nullopt, 120.0), "rom_min_deg");
  EXPECT_EQ(field(-40.0, 120.0), "rom_min_deg");
  EXPECT_EQ(field(0.0, 190.0), "rom_max_deg");
  EXPECT_EQ(field(50.0, 70.0), "rom_max_deg");  // 20° wide
  EXPECT_EQ(field(std::nan(""), 120.0), "rom_min_deg");
}

TEST_P(StorageTest, LegsPerSubject) {
  SubjectRepository subjects(*db_);
  auto subject = subjects.Create("L1", SubjectDetails{});
  ASSERT_TRUE(subject.ok());
  auto right = subjects.AddLeg(subject->id, Side::kRight);
  auto left = subjects.AddLeg(subject->id, Side::kLeft);
  ASSERT_TRUE(right.ok() && left.ok());
  auto again = subjects.AddLeg(subject->id, Side::kLeft);
  EXPECT_EQ(again.status().code(), api::ErrorCode::kAlreadyExists);
  EXPECT_EQ(again.status().field(), "side");
  auto legs = subjects.Legs(subject->id);
  ASSERT_TRUE(legs.ok());
  ASSERT_EQ(legs->size(), 2u);
  EXPECT_EQ((*legs)[0].side, Side::kRight);
  EXPECT_EQ((*legs)[1].side, Side::kLeft);
  auto got = subjects.GetLeg(left->id);
  ASSERT_TRUE(got.ok());
  EXPECT_EQ(got->subject_id, subject->id);
  EXPECT_EQ(subjects.GetLeg(12345).status().code(), api::ErrorCode::kNotFound);
  EXPECT_EQ(subjects.AddLeg(12345, Side::kLeft).status().code(), api::ErrorCode::kNotFound);
}

}  // namespace
}  // namespace fesbench::storage
