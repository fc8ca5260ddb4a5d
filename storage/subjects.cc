#include "storage/subjects.h"

#include <cmath>

#include "storage/row_helpers.h"

namespace fesbench::storage {
namespace {

constexpr std::string_view kRevisionColumns =
    "r.id, r.revision, r.age_years, r.sex, r.height_cm, r.weight_kg, r.shank_length_cm, "
    "r.calf_circumference_cm, r.corrects_id, r.reason, r.recorded_at_utc, r.recorded_by, "
    "r.rom_min_deg, r.rom_max_deg";

// Reads kRevisionColumns starting at column `first`.
api::Result<SubjectRevision> ReadRevision(const Statement& s, int first) {
  SubjectRevision revision;
  revision.id = s.Int64(first);
  revision.revision = static_cast<int>(s.Int64(first + 1));
  if (!s.IsNull(first + 2)) revision.details.age_years = static_cast<int>(s.Int64(first + 2));
  const auto sex = ParseSex(s.Text(first + 3));
  const auto recorded = api::ParseUtc(s.Text(first + 10));
  if (!sex || !recorded) return internal::BadStoredValue("subject revision");
  revision.details.sex = *sex;
  revision.details.height_cm = s.OptionalDouble(first + 4);
  revision.details.weight_kg = s.OptionalDouble(first + 5);
  revision.details.shank_length_cm = s.OptionalDouble(first + 6);
  revision.details.calf_circumference_cm = s.OptionalDouble(first + 7);
  revision.corrects_id = s.OptionalInt64(first + 8);
  revision.reason = s.Text(first + 9);
  revision.recorded_at = *recorded;
  revision.recorded_by = s.Text(first + 11);
  revision.details.rom_min_deg = s.OptionalDouble(first + 12);
  revision.details.rom_max_deg = s.OptionalDouble(first + 13);
  return revision;
}

// The subjects with their latest revision: `where` selects on s with the
// `key` values bound to ?1, ...
template <typename... Key>
api::Result<std::vector<Subject>> QuerySubjects(Connection& c, std::string_view where,
                                                std::string_view limit, const Key&... key) {
  // The page of subjects first, then their current revisions: a deep page
  // is an index seek on both engines (PostgreSQL would otherwise hash-join
  // every subject with every revision before it limits).
  const std::string sql =
      "SELECT s.id, s.code, s.created_at_utc, " + std::string(kRevisionColumns) +
      " FROM (SELECT s.id, s.code, s.created_at_utc FROM subjects s " + std::string(where) +
      " ORDER BY s.id " + std::string(limit) +
      ") s JOIN subject_revisions r ON r.subject_id = s.id"
      " AND r.revision = (SELECT MAX(revision) FROM subject_revisions WHERE subject_id = s.id)"
      " ORDER BY s.id";
  return internal::QueryRows(
      c, sql,
      [](const Statement& s) -> api::Result<Subject> {
        Subject subject;
        subject.id = s.Int64(0);
        subject.code = s.Text(1);
        const auto created = api::ParseUtc(s.Text(2));
        auto revision = ReadRevision(s, 3);
        if (!created) return internal::BadStoredValue("subject");
        if (!revision.ok()) return revision.status();
        subject.created_at = *created;
        subject.current = std::move(*revision);
        return subject;
      },
      key...);
}

api::Result<Subject> GetById(Connection& c, std::int64_t id) {
  return internal::One(QuerySubjects(c, "WHERE s.id = ?1", "", id), "subject", id);
}

api::Status InsertRevision(Connection& c, std::int64_t subject_id, int revision,
                           const SubjectDetails& d, std::optional<std::int64_t> corrects_id,
                           std::string_view reason, std::string_view recorded_by, api::UtcTime now) {
  std::optional<std::int64_t> age;
  if (d.age_years) age = *d.age_years;
  return internal::Execute(
      c,
      "INSERT INTO subject_revisions (subject_id, revision, age_years, sex, height_cm, weight_kg,"
      " shank_length_cm, calf_circumference_cm, corrects_id, reason, recorded_at_utc, recorded_by,"
      " rom_min_deg, rom_max_deg)"
      " VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14)",
      subject_id, revision, age, SexName(d.sex), d.height_cm, d.weight_kg, d.shank_length_cm,
      d.calf_circumference_cm, corrects_id, reason, api::FormatUtc(now), recorded_by, d.rom_min_deg,
      d.rom_max_deg);
}

api::Status CheckRange(const std::optional<double>& value, double low, double high,
                       const char* field) {
  if (!value) return api::Status::Ok();
  if (!std::isfinite(*value) || *value <= low || *value > high) {
    return api::Status::InvalidArgument(std::string(field) + " must be in (" + std::to_string(low) +
                                            ", " + std::to_string(high) + "]",
                                        field);
  }
  return api::Status::Ok();
}

api::Result<Leg> ReadLeg(const Statement& s) {
  Leg leg;
  leg.id = s.Int64(0);
  leg.subject_id = s.Int64(1);
  const auto side = ParseSide(s.Text(2));
  const auto created = api::ParseUtc(s.Text(3));
  if (!side || !created) return internal::BadStoredValue("leg");
  leg.side = *side;
  leg.created_at = *created;
  return leg;
}

}  // namespace


api::Status ValidateSubjectCode(std::string_view code) {
  if (code.empty() || code.size() > 32) {
    return api::Status::InvalidArgument("subject code must have 1 to 32 characters", "code");
  }
  for (char ch : code) {
    const bool ok = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') ||
                    (ch >= '0' && ch <= '9') || ch == '_' || ch == '-';
    if (!ok) {
      return api::Status::InvalidArgument(
          "subject code may hold only letters, digits, '_' and '-' (it is a pseudonym)", "code");
    }
  }
  return api::Status::Ok();
}

api::Status ValidateSubjectDetails(const SubjectDetails& d) {
  if (d.age_years && (*d.age_years < 0 || *d.age_years > 130)) {
    return api::Status::InvalidArgument("age_years must be in [0, 130]", "age_years");
  }
  if (auto s = CheckRange(d.height_cm, 30, 250, "height_cm"); !s.ok()) return s;
  if (auto s = CheckRange(d.weight_kg, 1, 400, "weight_kg"); !s.ok()) return s;
  if (auto s = CheckRange(d.shank_length_cm, 10, 80, "shank_length_cm"); !s.ok()) return s;
  if (auto s = CheckRange(d.calf_circumference_cm, 10, 100, "calf_circumference_cm"); !s.ok()) {
    return s;
  }
  if (d.rom_min_deg.has_value() != d.rom_max_deg.has_value()) {
    return api::Status::InvalidArgument(
        "give both ends of the range of motion (rom_min_deg and rom_max_deg) or neither",
        d.rom_min_deg ? "rom_max_deg" : "rom_min_deg");
  }
  if (!d.rom_min_deg) return api::Status::Ok();
  if (!std::isfinite(*d.rom_min_deg) || *d.rom_min_deg < -30.0 || *d.rom_min_deg > 60.0) {
    return api::Status::InvalidArgument(
        "rom_min_deg must be in [-30, 60] deg (hyperextension negative)", "rom_min_deg");
  }
  if (!std::isfinite(*d.rom_max_deg) || *d.rom_max_deg < 60.0 || *d.rom_max_deg > 180.0) {
    return api::Status::InvalidArgument("rom_max_deg must be in [60, 180] deg", "rom_max_deg");
  }
  if (*d.rom_max_deg - *d.rom_min_deg < 30.0) {
    return api::Status::InvalidArgument(
        "the range of motion must span at least 30 deg (rom_min_deg to rom_max_deg)",
        "rom_max_deg");
  }
  return api::Status::Ok();
}

api::Result<Subject> SubjectRepository::Create(std::string_view code,
                                               const SubjectDetails& details) {
  if (auto s = ValidateSubjectCode(code); !s.ok()) return s;
  if (auto s = ValidateSubjectDetails(details); !s.ok()) return s;
  return db_.Write([&](Connection& c) -> api::Result<Subject> {
    auto existing = internal::RowExists(c, "SELECT 1 FROM subjects WHERE code = ?1", code);
    if (!existing.ok()) return existing.status();
    if (*existing) {
      return api::Status::AlreadyExists("subject code '" + std::string(code) + "' already exists",
                                        "code");
    }
    const api::UtcTime now = db_.Now();
    auto id = internal::InsertRow(c, "INSERT INTO subjects (code, created_at_utc) VALUES (?1, ?2)",
                                  code, api::FormatUtc(now));
    if (!id.ok()) return id.status();
    if (auto s = InsertRevision(c, *id, 1, details, std::nullopt, "", "", now); !s.ok()) return s;
    return GetById(c, *id);
  });
}

api::Result<Subject> SubjectRepository::Get(std::int64_t subject_id) {
  return db_.Read([&](Connection& c) { return GetById(c, subject_id); });
}

api::Result<Subject> SubjectRepository::GetByCode(std::string_view code) {
  return db_.Read([&](Connection& c) -> api::Result<Subject> {
    auto subjects = QuerySubjects(c, "WHERE s.code = ?1", "", code);
    if (!subjects.ok()) return subjects.status();
    if (subjects->empty()) {
      return api::Status::NotFound("subject code '" + std::string(code) + "' not found");
    }
    return std::move(subjects->front());
  });
}

api::Result<std::vector<Subject>> SubjectRepository::List() {
  return db_.Read([&](Connection& c) { return QuerySubjects(c, "", ""); });
}

api::Result<std::vector<Subject>> SubjectRepository::ListPage(std::int64_t after_id,
                                                              std::size_t limit) {
  return db_.Read([&](Connection& c) {
    return QuerySubjects(c, "WHERE s.id > ?1", "LIMIT ?2", after_id,
                         static_cast<std::int64_t>(limit));
  });
}

api::Result<Subject> SubjectRepository::Correct(std::int64_t subject_id,
                                                const SubjectDetails& details,
                                                std::string_view reason,
                                                std::string_view recorded_by) {
  if (auto s = ValidateSubjectDetails(details); !s.ok()) return s;
  if (reason.empty()) {
    return api::Status::InvalidArgument("a correction needs a reason", "reason");
  }
  return db_.Write([&](Connection& c) {
    return internal::AppendCorrection(
        c, subject_id, GetById, [&](int revision, std::int64_t corrects_id) {
          return InsertRevision(c, subject_id, revision, details, corrects_id, reason, recorded_by,
                                db_.Now());
        });
  });
}

api::Result<std::vector<SubjectRevision>> SubjectRepository::Revisions(std::int64_t subject_id) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<SubjectRevision>> {
    if (auto s =
            internal::RequireRow(c, "SELECT 1 FROM subjects WHERE id = ?1", subject_id, "subject");
        !s.ok()) {
      return s;
    }
    return internal::QueryRows(
        c,
        "SELECT " + std::string(kRevisionColumns) +
            " FROM subject_revisions r WHERE r.subject_id = ?1"
            " ORDER BY r.revision",
        [](const Statement& s) { return ReadRevision(s, 0); }, subject_id);
  });
}

api::Result<Leg> SubjectRepository::AddLeg(std::int64_t subject_id, Side side) {
  return db_.Write([&](Connection& c) -> api::Result<Leg> {
    if (auto s =
            internal::RequireRow(c, "SELECT 1 FROM subjects WHERE id = ?1", subject_id, "subject");
        !s.ok()) {
      return s;
    }
    auto existing = internal::RowExists(c, "SELECT 1 FROM legs WHERE subject_id = ?1 AND side = ?2",
                                        subject_id, SideName(side));
    if (!existing.ok()) return existing.status();
    if (*existing) {
      return api::Status::AlreadyExists("subject " + std::to_string(subject_id) +
                                            " already has a " + std::string(SideName(side)) +
                                            " leg",
                                        "side");
    }
    const api::UtcTime now = db_.Now();
    auto id = internal::InsertRow(
        c, "INSERT INTO legs (subject_id, side, created_at_utc) VALUES (?1, ?2, ?3)", subject_id,
        SideName(side), api::FormatUtc(now));
    if (!id.ok()) return id.status();
    return Leg{*id, subject_id, side, now};
  });
}

api::Result<Leg> SubjectRepository::GetLeg(std::int64_t leg_id) {
  return db_.Read([&](Connection& c) {
    return internal::One(
        internal::QueryRows(c,
                            "SELECT id, subject_id, side, created_at_utc FROM legs WHERE id = ?1",
                            ReadLeg, leg_id),
        "leg", leg_id);
  });
}

api::Result<std::vector<Leg>> SubjectRepository::Legs(std::int64_t subject_id) {
  return db_.Read([&](Connection& c) -> api::Result<std::vector<Leg>> {
    if (auto s =
            internal::RequireRow(c, "SELECT 1 FROM subjects WHERE id = ?1", subject_id, "subject");
        !s.ok()) {
      return s;
    }
    return internal::QueryRows(
        c,
        "SELECT id, subject_id, side, created_at_utc FROM legs WHERE subject_id = ?1 ORDER BY id",
        ReadLeg, subject_id);
  });
}

}  // namespace fesbench::storage
