#pragma once

/// @file
/// Subjects (pseudonymous code and anthropometrics) and their legs
/// (docs/ARCHITECTURE.md). Anthropometrics are kept as revisions: a correction adds
/// a revision that points at the one it corrects; nothing is overwritten.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/status.h"
#include "api/subject.h"
#include "storage/database.h"

namespace fesbench::storage {

// Storage keeps the wire's vocabulary and details (api/subject.h).
using api::ParseSex;
using api::ParseSide;
using api::Sex;
using api::SexName;
using api::Side;
using api::SideName;
using api::SubjectDetails;

/// One recorded version of a subject's details.
struct SubjectRevision {
  std::int64_t id = 0;
  int revision = 1;  ///< 1 for the original, then 2, 3, …
  SubjectDetails details;
  std::optional<std::int64_t> corrects_id;  ///< the revision this one corrects.
  std::string reason;
  api::UtcTime recorded_at;
  std::string recorded_by;  ///< user name of who recorded it ("" if unknown).
};

/// A subject with its current (latest) details.
struct Subject {
  std::int64_t id = 0;
  std::string code;  ///< pseudonymous: [A-Za-z0-9_-], 1–32 characters.
  api::UtcTime created_at;
  SubjectRevision current;
};

struct Leg {
  std::int64_t id = 0;
  std::int64_t subject_id = 0;
  Side side = Side::kRight;
  api::UtcTime created_at;
};

/// Checks a pseudonymous code: 1–32 of [A-Za-z0-9_-] (no spaces, so no
/// names). kInvalidArgument with field "code" otherwise.
api::Status ValidateSubjectCode(std::string_view code);
/// Checks the ranges documented on SubjectDetails (field names the member).
api::Status ValidateSubjectDetails(const SubjectDetails& details);

class SubjectRepository {
 public:
  explicit SubjectRepository(Database& db) : db_(db) {}

  /// Errors: kInvalidArgument (bad code or details, field named),
  /// kAlreadyExists (field "code") for a code already in use.
  api::Result<Subject> Create(std::string_view code, const SubjectDetails& details);
  /// kNotFound for an unknown id or code.
  api::Result<Subject> Get(std::int64_t subject_id);
  api::Result<Subject> GetByCode(std::string_view code);
  /// Every subject, by id.
  api::Result<std::vector<Subject>> List();
  /// At most `limit` subjects with id > `after_id`, ascending (keyset paging
  /// on the primary key: O(log n + limit) however deep the page).
  api::Result<std::vector<Subject>> ListPage(std::int64_t after_id, std::size_t limit);
  /// Records corrected details as a new revision pointing at the current one.
  /// `reason` must not be empty (field "reason").
  api::Result<Subject> Correct(std::int64_t subject_id, const SubjectDetails& details,
                               std::string_view reason, std::string_view recorded_by = {});
  /// All revisions, oldest first.
  api::Result<std::vector<SubjectRevision>> Revisions(std::int64_t subject_id);

  /// Adds a leg. kNotFound for an unknown subject, kAlreadyExists (field
  /// "side") if the subject already has that leg.
  api::Result<Leg> AddLeg(std::int64_t subject_id, Side side);
  api::Result<Leg> GetLeg(std::int64_t leg_id);
  api::Result<std::vector<Leg>> Legs(std::int64_t subject_id);

 private:
  Database& db_;
};

}  // namespace fesbench::storage
