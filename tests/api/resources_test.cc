// The stored resources' wire types (api/subject.h, api/session.h,
// api/trial_summary.h, api/parameter_set_record.h, api/user.h, api/audit.h,
// api/import_result.h, api/envelope.h): each reads back what it writes,
// through text as a client receives it, and the readers ignore fields they
// do not know and name a mistyped one.

#include <gtest/gtest.h>

#include <chrono>
#include <limits>
#include <nlohmann/json.hpp>

#include "api/audit.h"
#include "api/envelope.h"
#include "api/import_result.h"
#include "api/job.h"
#include "api/parameter_set_record.h"
#include "api/session.h"
#include "api/subject.h"
#include "api/trial_summary.h"
#include "api/user.h"
#include "model/parameter_set.h"

namespace fesbench::api {
namespace {

using nlohmann::json;

// A time with microseconds, as the database keeps them.
UtcTime At(std::int64_t us) {
  return UtcTime(std::chrono::microseconds(1'795'000'000'123'456 + us));
}

// Writes `value`, sends it as text, reads it back.
template <typename T>
T RoundTrip(const T& value, json (*to)(const T&), Result<T> (*from)(const json&)) {
  Result<T> read = from(json::parse(to(value).dump()));
  EXPECT_TRUE(read.ok()) << read.status().ToString();
  return read.ok() ? *read : T{};
}

SubjectDetails SomeDetails() {
  SubjectDetails d;
  d.age_years = 54;
  d.sex = Sex::kFemale;
  d.height_cm = 171.5;
  d.weight_kg = 1.0 / 3.0 + 60.0;
  d.shank_length_cm = 41.25;
  d.rom_min_deg = -5.0;
  d.rom_max_deg = 135.0;
  return d;
}

SessionDetails SomeSessionDetails() {
  return {"2026-11-27", "shank, 20 cm below knee", 12.5, 38.0, "first visit"};
}

TEST(ResourcesWire, SubjectRoundTrips) {
  Subject s{7, "P-007", At(0), 3, SomeDetails(), {{11, Side::kLeft}, {12, Side::kRight}}};
  EXPECT_EQ(RoundTrip(s, &SubjectToJson, &SubjectFromJson), s);
  s.details = SubjectDetails{};  // nothing measured: every optional absent
  s.legs.clear();
  EXPECT_EQ(RoundTrip(s, &SubjectToJson, &SubjectFromJson), s);
}

TEST(ResourcesWire, SubjectRevisionRoundTrips) {
  SubjectRevisionView r{2, 1, "weight re-measured", "cora", At(5), SomeDetails()};
  EXPECT_EQ(RoundTrip(r, &SubjectRevisionToJson, &SubjectRevisionFromJson), r);
  r = SubjectRevisionView{1, std::nullopt, "", std::nullopt, At(1), {}};
  EXPECT_EQ(RoundTrip(r, &SubjectRevisionToJson, &SubjectRevisionFromJson), r);
}

TEST(ResourcesWire, SessionAndRevisionRoundTrip) {
  Session s{4, 7, 11, Side::kLeft, At(2), 2, SomeSessionDetails()};
  EXPECT_EQ(RoundTrip(s, &SessionToJson, &SessionFromJson), s);
  EXPECT_EQ(SessionToJson(s).at("date"), "2026-11-27");
  s.details.threshold_ma.reset();
  s.details.max_tolerated_ma.reset();
  EXPECT_EQ(RoundTrip(s, &SessionToJson, &SessionFromJson), s);
  SessionRevisionView r{2, 1, "threshold re-measured", "cora", At(3), SomeSessionDetails()};
  EXPECT_EQ(RoundTrip(r, &SessionRevisionToJson, &SessionRevisionFromJson), r);
}

TEST(ResourcesWire, TrialSummaryRoundTrips) {
  TrialSummary t{21, 4, 9, "ramp_irc", TrialKind::kRampIrc, 1200, 200.0, At(4)};
  EXPECT_EQ(RoundTrip(t, &TrialSummaryToJson, &TrialSummaryFromJson), t);
  EXPECT_EQ(TrialSummaryToJson(t).at("duration_s"), 6.0);
  t = TrialSummary{22, 4, std::nullopt, std::nullopt, std::nullopt, 0, 0.0, At(6)};
  EXPECT_EQ(RoundTrip(t, &TrialSummaryToJson, &TrialSummaryFromJson), t);
  EXPECT_TRUE(TrialSummaryToJson(t).at("duration_s").is_null());
}

TEST(ResourcesWire, TrialImportRecordRoundTrips) {
  TrialImportRecord r{"sto", "gait lab", json{{"kind", "free_swing_passive"}}, "cora", 5};
  EXPECT_EQ(RoundTrip(r, &TrialImportRecordToJson, &TrialImportRecordFromJson), r);
  auto of = TrialImportOf(json{{"id", 3}, {"import", TrialImportRecordToJson(r)}});
  ASSERT_TRUE(of.ok());
  EXPECT_EQ(*of, r);
  auto none = TrialImportOf(json{{"id", 3}});
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
}

TEST(ResourcesWire, ParameterSetSummaryRoundTrips) {
  ParameterSetSummary s{5,
                        7,
                        11,
                        2,
                        "joint_v1",
                        "ramp_correlation",
                        "free_swing",
                        "log_least_squares",
                        "0.1.0",
                        4,
                        At(7),
                        std::nullopt};
  EXPECT_EQ(RoundTrip(s, &ParameterSetSummaryToJson, &ParameterSetSummaryFromJson), s);
  s.approval = ApprovalState{};  // never approved: {"approved": false, "approval": null}
  EXPECT_EQ(RoundTrip(s, &ParameterSetSummaryToJson, &ParameterSetSummaryFromJson), s);
  s.approval = ApprovalState{true, Approval{"cora", 3, At(8), "matches the leg", 17}};
  EXPECT_EQ(RoundTrip(s, &ParameterSetSummaryToJson, &ParameterSetSummaryFromJson), s);
  s.approval->newest->run_id.reset();
  s.approval->newest->approved_by_user_id.reset();
  EXPECT_EQ(RoundTrip(s, &ParameterSetSummaryToJson, &ParameterSetSummaryFromJson), s);
}

TEST(ResourcesWire, StoredParameterSetRoundTrips) {
  StoredParameterSet set;
  set.summary = {5,
                 7,
                 11,
                 1,
                 "joint_v1",
                 "ramp_correlation",
                 "free_swing",
                 "log_least_squares",
                 "0.1.0",
                 std::nullopt,
                 At(9),
                 std::nullopt};
  set.trial_ids = {10, 11, 12};
  set.parameters = model::ExampleParameterSet();
  set.fit_notes = {"The passive fit saw little of the knee's range."};
  EXPECT_EQ(RoundTrip(set, &StoredParameterSetToJson, &StoredParameterSetFromJson), set);
  set.summary.approval = ApprovalState{false, Approval{"cora", 3, At(10), "first", std::nullopt}};
  EXPECT_EQ(RoundTrip(set, &StoredParameterSetToJson, &StoredParameterSetFromJson), set);
}

TEST(ResourcesWire, UsersAndTokensRoundTrip) {
  User u{3, "cora", Role::kClinician, At(11), false};
  EXPECT_EQ(RoundTrip(u, &UserToJson, &UserFromJson), u);
  // GET /me: id, name and role only.
  const Result<User> me = UserFromJson(json::parse(SignedInUserToJson(u).dump()));
  ASSERT_TRUE(me.ok());
  EXPECT_EQ(me->name, "cora");
  EXPECT_EQ(me->role, Role::kClinician);
  TokenInfo t{8,
              3,
              "cora",
              "laptop",
              "2026-11-27T10:00:00.000000Z",
              std::nullopt,
              "2026-11-28T10:00:00.000000Z"};
  EXPECT_EQ(RoundTrip(t, &TokenInfoToJson, &TokenInfoFromJson), t);
  EXPECT_EQ(TokenInfoToJson(t).at("revoked"), true);
  IssuedTokenView issued{8, 3, "laptop", "fsb_0123", At(12)};
  EXPECT_EQ(RoundTrip(issued, &IssuedTokenToJson, &IssuedTokenFromJson), issued);
  issued.expires_at.reset();
  EXPECT_EQ(RoundTrip(issued, &IssuedTokenToJson, &IssuedTokenFromJson), issued);
}

TEST(ResourcesWire, AuditEntryRoundTrips) {
  AuditEntry e{40, At(13), {3, "cora", "POST /api/v1/subjects", "subjects/7", "code=P-007", "201"}};
  EXPECT_EQ(RoundTrip(e, &AuditEntryToJson, &AuditEntryFromJson), e);
  e.entry.user_id.reset();
  EXPECT_EQ(RoundTrip(e, &AuditEntryToJson, &AuditEntryFromJson), e);
}

TEST(ResourcesWire, ImportResultRoundTrips) {
  ImportResult r{{{30, 5, "ramp_irc"}, {31, std::nullopt, "free_swing_passive"}},
                 {{6, 2, "parameter set 2"}},
                 {"predictions were left out"}};
  EXPECT_EQ(RoundTrip(r, &ImportResultToJson, &ImportResultFromJson), r);
}

TEST(ResourcesWire, PageAndErrorEnvelopes) {
  Page page{{json{{"id", 1}}, json{{"id", 2}}}, "abc"};
  EXPECT_EQ(RoundTrip(page, &PageToJson, &PageFromJson), page);
  page.next_cursor.reset();
  EXPECT_EQ(RoundTrip(page, &PageToJson, &PageFromJson), page);
  EXPECT_FALSE(PageFromJson(json{{"next_cursor", nullptr}}).ok());

  const Status error = Status::InvalidArgument("must be left or right", "leg");
  const std::optional<Status> read = ErrorAnswerFromJson(ErrorAnswerToJson(error));
  ASSERT_TRUE(read.has_value());
  EXPECT_EQ(read->code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(read->message(), "must be left or right");
  EXPECT_EQ(read->field(), "leg");
  EXPECT_FALSE(ErrorAnswerFromJson(json{{"id", 1}}).has_value());
}

TEST(ResourcesWire, ReadersIgnoreUnknownFieldsAndNameMistypedOnes) {
  json j = SubjectToJson({7, "P-007", At(0), 1, SomeDetails(), {{11, Side::kLeft}}});
  j["added_by_a_newer_server"] = {{"x", 1}};
  EXPECT_TRUE(SubjectFromJson(j).ok());

  j["legs"][0]["side"] = 3;
  Result<Subject> bad = SubjectFromJson(j);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(bad.status().field(), "legs[0].side");

  json session = SessionToJson({4, 7, 11, Side::kLeft, At(2), 1, SomeSessionDetails()});
  session["details"]["threshold_ma"] = "twelve";
  EXPECT_EQ(SessionFromJson(session).status().field(), "details.threshold_ma");
  session.erase("id");
  EXPECT_EQ(SessionFromJson(session).status().field(), "id");

  // An enum name the client does not know is the reader's failure, not a default.
  json user = UserToJson({3, "cora", Role::kAdmin, At(1), true});
  user["role"] = "superuser";
  EXPECT_EQ(UserFromJson(user).status().field(), "role");
}

TEST(ResourcesWire, CorrectionRequestSetsAndClearsTheNamedFields) {
  CorrectionRequest<SubjectDetails> request{
      "re-measured", SomeDetails(), {"weight_kg", "sex"}, {"height_cm"}};
  const json body = CorrectionRequestToJson(request, &SubjectDetailsToJson);
  EXPECT_EQ(body.at("reason"), "re-measured");
  EXPECT_EQ(body.at("details"),
            (json{{"weight_kg", 1.0 / 3.0 + 60.0}, {"sex", "female"}, {"height_cm", nullptr}}));
}

TEST(ResourcesWire, NewRecordRequestsWriteWhatWasGiven) {
  NewSubjectRequest subject{"P-008", {}, {Side::kLeft}};
  EXPECT_EQ(NewSubjectRequestToJson(subject), (json{{"code", "P-008"}, {"legs", {"left"}}}));
  subject.details.height_cm = 180.0;
  EXPECT_EQ(NewSubjectRequestToJson(subject).at("details"),
            (json{{"height_cm", 180.0}, {"sex", "undisclosed"}}));
  NewSessionRequest session{Side::kRight, {"2026-11-27", "", 10.0, std::nullopt, ""}};
  EXPECT_EQ(NewSessionRequestToJson(session),
            (json{{"leg", "right"}, {"date", "2026-11-27"}, {"threshold_ma", 10.0}}));
  EXPECT_EQ(NewUserRequestToJson({"dan", Role::kAnalyst}),
            (json{{"name", "dan"}, {"role", "analyst"}}));
  EXPECT_EQ(NewTokenRequestToJson({3, "", 3600}), (json{{"user_id", 3}, {"expires_in_s", 3600}}));
}

}  // namespace
}  // namespace fesbench::api
