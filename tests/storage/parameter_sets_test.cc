#include "storage/parameter_sets.h"

#include <gtest/gtest.h>

#include <memory>
#include <nlohmann/json.hpp>
#include <tuple>

#include "api/parameter_set_json.h"
#include "storage/row_helpers.h"
#include "storage/trials.h"
#include "storage_test_util.h"

namespace fesbench::storage {
namespace {

using testing::Epoch2026;
using testing::MakeTrial;
using testing::StorageTest;

model::ParameterSet Params(const std::string& irc_method, const std::string& passive_method) {
  model::ParameterSet p = model::ExampleParameterSet();
  p.provenance.irc_method = irc_method;
  p.provenance.passive_method = passive_method;
  p.provenance.active_method = "log_least_squares";
  return p;
}

TEST_P(StorageTest, ParameterSetRoundTripWithProvenance) {
  const Session session = MakeSession("P1");
  TrialRepository trials(*db_);
  auto t1 = trials.Insert({session.id, std::nullopt}, MakeTrial(20));
  auto t2 = trials.Insert({session.id, std::nullopt}, MakeTrial(20, 0.5));
  ASSERT_TRUE(t1.ok() && t2.ok());
  model::ParameterSet params = Params("ramp_correlation", "free_swing");
  params.provenance.trial_ids = {*t2, *t1};
  params.provenance.active_trial_id = *t1;
  params.contraction.pole_per_s = 23.5;

  ParameterSetRepository sets(*db_);
  auto stored =
      sets.Insert({session.subject_id, session.leg_id, params, std::nullopt, std::nullopt});
  ASSERT_TRUE(stored.ok()) << stored.status().ToString();
  EXPECT_EQ(stored->version, 1);
  EXPECT_EQ(stored->model, "full");
  EXPECT_EQ(stored->software_version, StorageSoftwareVersion());

  auto got = sets.Get(stored->id);
  ASSERT_TRUE(got.ok()) << got.status().ToString();
  model::ParameterSet expected = params;
  expected.provenance.software_version = std::string(StorageSoftwareVersion());
  EXPECT_EQ(got->params, expected);
  EXPECT_EQ(got->trial_ids, (std::vector<std::int64_t>{*t1, *t2}));
  EXPECT_EQ(got->params.contraction.pole_per_s, 23.5);

  // A refit is a new version pointing at the one it supersedes.
  params.contraction.pole_per_s = 24.0;
  auto refit = sets.Insert({session.subject_id, session.leg_id, params, stored->id, std::nullopt});
  ASSERT_TRUE(refit.ok());
  EXPECT_EQ(refit->version, 2);
  EXPECT_EQ(refit->supersedes_id, stored->id);
  auto latest = sets.Latest(session.subject_id, session.leg_id);
  ASSERT_TRUE(latest.ok());
  EXPECT_EQ(latest->summary.id, refit->id);
  auto first = sets.Get(stored->id);
  ASSERT_TRUE(first.ok());
  EXPECT_EQ(first->params.contraction.pole_per_s, 23.5);  // never overwritten

  auto json_text = sets.ExportJson(stored->id);
  ASSERT_TRUE(json_text.ok());
  auto parsed = api::ParameterSetFromJson(nlohmann::json::parse(*json_text));
  ASSERT_TRUE(parsed.ok());
  EXPECT_EQ(*parsed, expected);
}

// A set names the run that identified it (migration 13): found by run.
TEST_P(StorageTest, ASetNamesItsRun) {
  const Session session = MakeSession("R1");
  SessionRepository sessions(*db_);
  auto run = sessions.CreateRun(session.id, {"rapid_parameterisation", "1", "{}"});
  auto other = sessions.CreateRun(session.id, {"free_swing", "1", "{}"});
  ASSERT_TRUE(run.ok() && other.ok());
  ParameterSetRepository sets(*db_);
  NewParameterSet set{session.subject_id, session.leg_id, Params("ramp_correlation", "free_swing"),
                      std::nullopt, std::nullopt};
  set.run_id = run->id;
  auto stored = sets.Insert(set);
  ASSERT_TRUE(stored.ok()) << stored.status().ToString();
  EXPECT_EQ(stored->run_id, run->id);
  auto got = sets.Get(stored->id);
  ASSERT_TRUE(got.ok());
  EXPECT_EQ(got->summary.run_id, run->id);
  auto by_run = sets.IdForRun(run->id);
  ASSERT_TRUE(by_run.ok());
  EXPECT_EQ(*by_run, stored->id);
  auto none = sets.IdForRun(other->id);
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
  set.run_id = 999;  // no such run
  EXPECT_EQ(sets.Insert(set).status().code(), api::ErrorCode::kInvalidArgument);
}

// Migration 15: a clinician's approval makes a set its leg's approved set;
// the newest approval wins, earlier ones stay in history, nothing is
// overwritten.
TEST_P(StorageTest, TheNewestApprovalMakesALegsApprovedSet) {
  const Session session = MakeSession("AP1");
  const Session other = MakeSession("AP2");
  ParameterSetRepository sets(*db_);
  auto insert = [&](const Session& s) {
    auto stored = sets.Insert({s.subject_id, s.leg_id, Params("ramp_correlation", "free_swing"),
                               std::nullopt, std::nullopt});
    EXPECT_TRUE(stored.ok()) << stored.status().ToString();
    return stored->id;
  };
  const std::int64_t first = insert(session);
  const std::int64_t second = insert(session);
  const std::int64_t elsewhere = insert(other);

  auto none = sets.Approved(session.leg_id);
  EXPECT_EQ(none.status().code(), api::ErrorCode::kNotFound);
  EXPECT_NE(none.status().message().find("no parameter set is approved"), std::string::npos);
  EXPECT_FALSE(sets.LegApproval(session.leg_id)->has_value());

  auto approved = sets.Approve({first, std::nullopt, "cora", std::nullopt, "rapid run on day 1"});
  ASSERT_TRUE(approved.ok()) << approved.status().ToString();
  EXPECT_TRUE(approved->current);
  EXPECT_EQ(approved->leg_id, session.leg_id);
  EXPECT_EQ(sets.Approved(session.leg_id)->summary.id, first);
  EXPECT_EQ(sets.Latest(session.subject_id, session.leg_id)->summary.id, second)
      << "the newest set is not the approved one";
  auto again = sets.Approve({first, std::nullopt, "cora", std::nullopt, "twice"});
  EXPECT_EQ(again.status().code(), api::ErrorCode::kFailedPrecondition);
  EXPECT_NE(again.status().message().find("already"), std::string::npos);

  ASSERT_TRUE(sets.Approve({second, std::nullopt, "cora", std::nullopt, "refit looks right"}).ok());
  EXPECT_EQ(sets.Approved(session.leg_id)->summary.id, second);
  auto history = sets.Approvals(first);
  ASSERT_TRUE(history.ok());
  ASSERT_EQ(history->size(), 1u);
  EXPECT_FALSE(history->front().current) << "a later approval of the leg supersedes it";
  EXPECT_EQ(history->front().approved_by, "cora");
  EXPECT_EQ(history->front().note, "rapid run on day 1");
  auto latest = sets.LatestApprovals({first, second, elsewhere});
  ASSERT_TRUE(latest.ok());
  ASSERT_EQ(latest->size(), 2u);
  EXPECT_EQ(latest->at(1).parameter_set_id, second);
  EXPECT_TRUE(latest->at(1).current);
  // Back to the first: the history keeps every approval, newest first.
  ASSERT_TRUE(sets.Approve({first, std::nullopt, "cora", std::nullopt, "back to day 1"}).ok());
  EXPECT_EQ(*sets.ApprovedHistory(session.leg_id, 20), (std::vector<std::int64_t>{first, second}));
  EXPECT_EQ(sets.Approvals(first)->size(), 2u);
  EXPECT_FALSE(sets.Approved(other.leg_id).ok()) << "another leg's approvals are its own";

  EXPECT_EQ(sets.Approve({second, std::nullopt, "cora", std::nullopt, ""}).status().field(),
            "note");
  EXPECT_EQ(sets.Approve({second, std::nullopt, "cora", std::nullopt, std::string(501, 'x')})
                .status()
                .field(),
            "note");
  EXPECT_EQ(sets.Approve({999, std::nullopt, "cora", std::nullopt, "x"}).status().code(),
            api::ErrorCode::kNotFound);
  EXPECT_EQ(sets.Approve({second, std::nullopt, "cora", 999, "x"}).status().code(),
            api::ErrorCode::kNotFound);
  auto update = db_->Write([](Connection& c) -> api::Status {
    auto s = c.Prepare("UPDATE parameter_set_approvals SET note = 'rewritten'");
    if (!s.ok()) return s.status();
    return s->Run();
  });
  EXPECT_EQ(update.code(), api::ErrorCode::kFailedPrecondition) << "approvals are append-only";
}

// Migration 15 on a database of schema 14: a set a bench run stored is
// approved by that run, the newest such set of the leg is its approved set,
// and a set no run stored stays a candidate.
TEST_P(StorageTest, MigrationFifteenApprovesTheSetsRunsStored) {
  std::unique_ptr<::fesbench::testing::ScratchDatabase> scratch;
  DatabaseOptions v14 = Options();
  if (GetParam() == Engine::kPostgres) {
    scratch = std::make_unique<::fesbench::testing::ScratchDatabase>();
    ASSERT_TRUE(scratch->ok()) << scratch->skip_reason();
    v14.path = scratch->url();
  } else {
    v14.path = (dir_ / "v14.db").string();
  }
  v14.target_schema_version = 14;
  std::int64_t leg_id = 0, run_id = 0, older = 0, by_run = 0, candidate = 0;
  {
    auto db = Database::Open(v14);
    ASSERT_TRUE(db.ok()) << db.status().ToString();
    // The subject and leg as schema 14 has them (the repository reads the
    // columns of later migrations).
    std::int64_t subject_id = 0;
    api::Status made = (*db)->Write([&](Connection& c) -> api::Status {
      const std::string now = api::FormatUtc((*db)->Now());
      auto subject =
          internal::InsertRow(c, "INSERT INTO subjects (code, created_at_utc) VALUES (?1, ?2)",
                              std::string("M15"), now);
      if (!subject.ok()) return subject.status();
      subject_id = *subject;
      if (auto st = internal::Execute(
              c,
              "INSERT INTO subject_revisions (subject_id, revision, sex, recorded_at_utc)"
              " VALUES (?1, 1, 'undisclosed', ?2)",
              subject_id, now);
          !st.ok()) {
        return st;
      }
      auto leg = internal::InsertRow(
          c, "INSERT INTO legs (subject_id, side, created_at_utc) VALUES (?1, 'left', ?2)",
          subject_id, now);
      if (!leg.ok()) return leg.status();
      leg_id = *leg;
      return api::Status::Ok();
    });
    ASSERT_TRUE(made.ok()) << made.ToString();
    SessionDetails details;
    details.date = "2026-01-02";
    auto session = SessionRepository(**db).Create(subject_id, leg_id, details);
    ASSERT_TRUE(session.ok());
    // Runs as schema 14 stores them (the repository reads columns of later
    // migrations).
    auto run = [&](const char* protocol) {
      return (*db)->Write([&](Connection& c) {
        return internal::InsertRow(c,
                                   "INSERT INTO runs (session_id, protocol_name, protocol_version,"
                                   " parameters_json, created_at_utc) VALUES (?1, ?2, '1', '{}', ?3)",
                                   session->id, std::string(protocol), api::FormatUtc((*db)->Now()));
      });
    };
    auto first = run("rapid_parameterisation");
    auto second = run("daily_check");
    ASSERT_TRUE(first.ok() && second.ok());
    run_id = *second;
    ParameterSetRepository sets(**db);
    auto insert = [&](std::optional<std::int64_t> run) {
      NewParameterSet set{subject_id, leg_id, Params("ramp_correlation", "free_swing"),
                          std::nullopt, std::nullopt};
      set.run_id = run;
      auto stored = sets.Insert(set);
      EXPECT_TRUE(stored.ok()) << stored.status().ToString();
      return stored->id;
    };
    older = insert(*first);
    by_run = insert(*second);
    candidate = insert(std::nullopt);  // an import or a re-identification
  }
  DatabaseOptions latest = v14;
  latest.target_schema_version.reset();
  auto db = Database::Open(latest);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  ParameterSetRepository sets(**db);
  auto approved = sets.Approved(leg_id);
  ASSERT_TRUE(approved.ok()) << approved.status().ToString();
  EXPECT_EQ(approved->summary.id, by_run) << "the newest set a run stored, not the newest set";
  auto approval = sets.LegApproval(leg_id);
  ASSERT_TRUE(approval.ok() && approval->has_value());
  EXPECT_EQ((*approval)->run_id, run_id);
  EXPECT_EQ((*approval)->approved_by, "run " + std::to_string(run_id));
  EXPECT_FALSE((*approval)->approved_by_user_id.has_value());
  EXPECT_EQ(sets.Approvals(older)->size(), 1u);
  EXPECT_TRUE(sets.Approvals(candidate)->empty());
}

// A stored set is an event, raised after its transaction commits
// (also when the insert is nested in a caller's transaction), never for a
// transaction that rolls back.
TEST_P(StorageTest, StoredSetsNotifyTheListenerAfterCommitOnly) {
  const Session session = MakeSession("EV1");
  std::vector<Database::ParameterSetStored> seen;
  db_->SetParameterSetListener([&](const Database::ParameterSetStored& e) { seen.push_back(e); });
  ParameterSetRepository sets(*db_);
  const NewParameterSet set{session.subject_id, session.leg_id, Params("ramp_correlation", "free_swing"),
                            std::nullopt, std::nullopt};

  auto alone = sets.Insert(set);
  ASSERT_TRUE(alone.ok()) << alone.status().ToString();
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].id, alone->id);
  EXPECT_EQ(seen[0].subject_id, session.subject_id);
  EXPECT_EQ(seen[0].leg_id, session.leg_id);

  std::int64_t nested_id = 0;
  api::Status committed = db_->Write([&](Connection&) -> api::Status {
    auto inner = sets.Insert(set);
    if (!inner.ok()) return inner.status();
    nested_id = inner->id;
    EXPECT_EQ(seen.size(), 1u) << "notified before the commit";
    return api::Status::Ok();
  });
  ASSERT_TRUE(committed.ok()) << committed.ToString();
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[1].id, nested_id);

  api::Status rolled_back = db_->Write([&](Connection&) -> api::Status {
    auto inner = sets.Insert(set);
    if (!inner.ok()) return inner.status();
    return api::Status::InvalidArgument("a later step failed", "x");
  });
  EXPECT_FALSE(rolled_back.ok());
  EXPECT_EQ(seen.size(), 2u) << "notified for a rolled-back set";

  db_->SetParameterSetListener({});
  ASSERT_TRUE(sets.Insert(set).ok());
  EXPECT_EQ(seen.size(), 2u);
}

TEST_P(StorageTest, HistoryFiltersBySubjectLegMethodAndDate) {
  const Session a = MakeSession("H1");
  const Session b = MakeSession("H2");
  auto left = SubjectRepository(*db_).AddLeg(a.subject_id, Side::kLeft);
  ASSERT_TRUE(left.ok());
  ParameterSetRepository sets(*db_);
  // Subject a: day 0..9 alternating methods on the right leg, days 10, 11 on the left.
  for (int day = 0; day < 12; ++day) {
    const bool right = day < 10;
    auto params = Params(day % 2 == 0 ? "ramp_correlation" : "twitch_deconvolution", "free_swing");
    NewParameterSet set{a.subject_id, right ? a.leg_id : left->id, params, std::nullopt,
                        Epoch2026() + std::chrono::days(day)};
    ASSERT_TRUE(sets.Insert(set).ok());
    ASSERT_TRUE(sets.Insert({b.subject_id, b.leg_id, params, std::nullopt,
                             Epoch2026() + std::chrono::days(day)})
                    .ok());
  }
  auto all = sets.History({a.subject_id, std::nullopt, std::nullopt, std::nullopt, std::nullopt});
  ASSERT_TRUE(all.ok());
  ASSERT_EQ(all->size(), 12u);
  for (const auto& s : *all) EXPECT_EQ(s.subject_id, a.subject_id);
  EXPECT_EQ(api::FormatUtc(all->front().created_at), "2026-01-01T00:00:00.000000Z");
  EXPECT_EQ(all->back().version, 2);  // second set of the left leg

  auto right_leg = sets.History({a.subject_id, a.leg_id, std::nullopt, std::nullopt, std::nullopt});
  ASSERT_TRUE(right_leg.ok());
  EXPECT_EQ(right_leg->size(), 10u);
  EXPECT_EQ(right_leg->back().version, 10);

  auto twitch =
      sets.History({a.subject_id, a.leg_id, "twitch_deconvolution", std::nullopt, std::nullopt});
  ASSERT_TRUE(twitch.ok());
  EXPECT_EQ(twitch->size(), 5u);
  auto passive =
      sets.History({a.subject_id, std::nullopt, "free_swing", std::nullopt, std::nullopt});
  ASSERT_TRUE(passive.ok());
  EXPECT_EQ(passive->size(), 12u);

  // [day 3, day 7): days 3, 4, 5, 6.
  auto range =
      sets.History({a.subject_id, std::nullopt, std::nullopt, Epoch2026() + std::chrono::days(3),
                    Epoch2026() + std::chrono::days(7)});
  ASSERT_TRUE(range.ok());
  ASSERT_EQ(range->size(), 4u);
  EXPECT_EQ(range->front().version, 4);
  EXPECT_EQ(range->back().version, 7);

  HistoryQuery limited{a.subject_id, std::nullopt, std::nullopt, std::nullopt, std::nullopt, 3};
  auto first3 = sets.History(limited);
  ASSERT_TRUE(first3.ok());
  EXPECT_EQ(first3->size(), 3u);

  EXPECT_EQ(
      sets.History({999, std::nullopt, std::nullopt, std::nullopt, std::nullopt}).status().code(),
      api::ErrorCode::kNotFound);

  // The history query is an index range scan, not a table scan.
  ExpectIndexRange(
      "SELECT id FROM parameter_sets WHERE subject_id = ?1"
      " AND created_at_utc >= ?2 AND created_at_utc < ?3 ORDER BY created_at_utc, id",
      "parameter_sets_subject_time");
}

// The list's keyset pages: every filter in the query, pages in id order
// that join up without gaps or repeats, and each page shape a seek on an
// index (never a scan of the table or a sort).
TEST_P(StorageTest, ParameterSetListPagesByKeyWithEveryFilter) {
  const Session a = MakeSession("K1");
  const Session b = MakeSession("K2");
  auto left = SubjectRepository(*db_).AddLeg(a.subject_id, Side::kLeft);
  ASSERT_TRUE(left.ok());
  ParameterSetRepository sets(*db_);
  std::vector<std::int64_t> of_a;
  for (int day = 0; day < 12; ++day) {
    auto params = Params(day % 2 == 0 ? "ramp_correlation" : "twitch_deconvolution", "free_swing");
    auto in_a = sets.Insert({a.subject_id, day < 10 ? a.leg_id : left->id, params, std::nullopt,
                             Epoch2026() + std::chrono::days(day)});
    auto in_b = sets.Insert(
        {b.subject_id, b.leg_id, params, std::nullopt, Epoch2026() + std::chrono::days(day)});
    ASSERT_TRUE(in_a.ok() && in_b.ok());
    of_a.push_back(in_a->id);
  }
  // Pages of 5 over subject a: 5 + 5 + 2, in id order, nothing twice.
  std::vector<std::int64_t> paged;
  ParameterSetListQuery q;
  q.subject_id = a.subject_id;
  q.limit = 5;
  for (int page = 0; page < 4; ++page) {
    auto rows = sets.List(q);
    ASSERT_TRUE(rows.ok()) << rows.status().ToString();
    for (const auto& s : *rows) paged.push_back(s.id);
    if (rows->size() < q.limit) break;
    q.after_id = rows->back().id;
  }
  EXPECT_EQ(paged, of_a);

  ParameterSetListQuery filtered;
  filtered.subject_id = a.subject_id;
  filtered.leg_id = a.leg_id;
  filtered.method = "twitch_deconvolution";
  filtered.from = Epoch2026() + std::chrono::days(3);
  filtered.to = Epoch2026() + std::chrono::days(8);
  auto rows = sets.List(filtered);
  ASSERT_TRUE(rows.ok());
  std::vector<int> versions;
  for (const auto& s : *rows) versions.push_back(s.version);
  EXPECT_EQ(versions, (std::vector<int>{4, 6, 8}));  // days 3, 5, 7

  ParameterSetListQuery everyone;
  everyone.after_id = of_a[5];
  everyone.limit = 3;
  rows = sets.List(everyone);
  ASSERT_TRUE(rows.ok());
  ASSERT_EQ(rows->size(), 3u);
  EXPECT_GT(rows->front().id, of_a[5]);
  ParameterSetListQuery unknown;
  unknown.subject_id = 999;
  EXPECT_EQ(sets.List(unknown).status().code(), api::ErrorCode::kNotFound);

  const std::tuple<const char*, const char*, const char*> shapes[] = {
      {"SELECT id FROM parameter_sets WHERE id > ?1 ORDER BY id LIMIT ?7", "", "parameter_sets"},
      {"SELECT id FROM parameter_sets WHERE id > ?1 AND subject_id = ?2 ORDER BY id LIMIT ?7",
       "parameter_sets_subject_id", ""},
      {"SELECT id FROM parameter_sets WHERE id > ?1 AND subject_id = ?2 AND leg_id = ?3"
       " ORDER BY id LIMIT ?7",
       "parameter_sets_leg_id", ""},
      {"SELECT id FROM trials WHERE session_id = ?1 AND id > ?2 ORDER BY id LIMIT ?3",
       "trials_session", ""},
      {"SELECT id FROM runs WHERE session_id = ?1 AND id > ?2 ORDER BY id LIMIT ?3",
       "runs_session", ""},
  };
  for (const auto& [sql, index, primary_key_of] : shapes) {
    ExpectIndexRange(sql, index, primary_key_of);
  }
}

TEST_P(StorageTest, ParameterSetBadInputNamesTheProblem) {
  const Session a = MakeSession("Q1");
  const Session b = MakeSession("Q2");
  ParameterSetRepository sets(*db_);
  auto params = Params("ramp_correlation", "free_swing");
  EXPECT_EQ(sets.Insert({999, a.leg_id, params, std::nullopt, std::nullopt}).status().message(),
            "subject 999 not found");
  EXPECT_EQ(
      sets.Insert({a.subject_id, b.leg_id, params, std::nullopt, std::nullopt}).status().field(),
      "leg_id");
  auto trial_b = TrialRepository(*db_).Insert({b.id, std::nullopt}, MakeTrial(5));
  ASSERT_TRUE(trial_b.ok());
  auto with_b = params;
  with_b.provenance.trial_ids = {*trial_b};
  auto foreign = sets.Insert({a.subject_id, a.leg_id, with_b, std::nullopt, std::nullopt});
  EXPECT_EQ(foreign.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(foreign.status().field(), "provenance.trial_ids[0]");
  auto with_missing = params;
  with_missing.provenance.trial_ids = {4242};
  auto missing = sets.Insert({a.subject_id, a.leg_id, with_missing, std::nullopt, std::nullopt});
  EXPECT_EQ(missing.status().code(), api::ErrorCode::kNotFound);
  EXPECT_EQ(missing.status().field(), "provenance.trial_ids[0]");
  auto bad = params;
  bad.passive.inertia_kgm2 = -1.0;
  auto invalid = sets.Insert({a.subject_id, a.leg_id, bad, std::nullopt, std::nullopt});
  EXPECT_EQ(invalid.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(invalid.status().field(), "passive.inertia_kgm2");
  auto not_utf8 = params;
  not_utf8.provenance.irc_method = "ramp\xff";
  auto refused = sets.Insert({a.subject_id, a.leg_id, not_utf8, std::nullopt, std::nullopt});
  EXPECT_EQ(refused.status().code(), api::ErrorCode::kInvalidArgument);
  auto other = sets.Insert({b.subject_id, b.leg_id, params, std::nullopt, std::nullopt});
  ASSERT_TRUE(other.ok());
  EXPECT_EQ(sets.Insert({a.subject_id, a.leg_id, params, other->id, std::nullopt}).status().field(),
            "supersedes_id");
  EXPECT_EQ(sets.Get(999).status().code(), api::ErrorCode::kNotFound);
  EXPECT_EQ(sets.ExportJson(999).status().code(), api::ErrorCode::kNotFound);
  EXPECT_EQ(sets.Latest(a.subject_id, a.leg_id).status().code(), api::ErrorCode::kNotFound);
}

}  // namespace
}  // namespace fesbench::storage
