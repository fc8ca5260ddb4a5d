// BenchService: bench info, the virtual subject read and replaced by an
// admin between runs only (audited), refusals on a bench that is not
// simulated, and a latched hardware e-stop surviving a subject change.
#include "server/services/bench_service.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "api/virtual_subject.h"
#include "server/bench/replay_bench.h"
#include "storage/audit_log.h"
#include "storage/subjects.h"
#include "storage/users.h"
#include "tests/server/run_service_rig.h"

namespace fesbench::server::services {
namespace {

using namespace std::chrono_literals;

using test::TempDir;  // run_service_rig.h

struct Rig {
  explicit Rig(double time_scale = 0.0) : dir(TempDir()) {
    storage::DatabaseOptions dbo;
    dbo.path = (dir / "fesbench.db").string();
    dbo.synchronous = storage::Synchronous::kNormal;
    auto opened = storage::Database::Open(dbo);
    EXPECT_TRUE(opened.ok()) << opened.status().ToString();
    db = std::move(opened).value();
    auto a = storage::UserRepository(*db).CreateUser("adam", storage::Role::kAdmin);
    EXPECT_TRUE(a.ok());
    admin = Actor{a->id, "adam", Role::kAdmin};
    auto c = storage::UserRepository(*db).CreateUser("cora", storage::Role::kClinician);
    EXPECT_TRUE(c.ok());
    clinician = Actor{c->id, "cora", Role::kClinician};

    SimulatedBenchOptions bo;
    bo.time_scale = time_scale;
    bench = SwappableSimulatedBench::Create(DrawVirtualSubject(21), bo).value();
    RunServiceConfig config;
    config.time_scale = time_scale;
    config.arm_watchdog = false;
    runs = std::make_unique<RunService>(*db, *bench, hub, config);
    service = std::make_unique<BenchService>(*db, *runs, bench.get());
  }
  ~Rig() {
    service.reset();
    runs.reset();
    db.reset();
    std::filesystem::remove_all(dir);
  }

  std::filesystem::path dir;
  std::unique_ptr<storage::Database> db;
  Actor admin, clinician;
  std::unique_ptr<SwappableSimulatedBench> bench;
  SampleHub hub;
  std::unique_ptr<RunService> runs;
  std::unique_ptr<BenchService> service;
};

TEST(BenchService, InfoReportsKindLimitsTimeScaleAndState) {
  Rig rig(0.0);
  const BenchInfo info = rig.service->Info();
  EXPECT_EQ(info.kind, "sim");
  EXPECT_TRUE(info.simulated);
  EXPECT_DOUBLE_EQ(info.time_scale, 0.0);
  EXPECT_DOUBLE_EQ(info.limits.max_stim_ma, 100.0);
  EXPECT_DOUBLE_EQ(info.limits.min_angle_deg, 10.0);
  EXPECT_DOUBLE_EQ(info.limits.max_angle_deg, 110.0);
  EXPECT_FALSE(info.state.busy);
  EXPECT_FALSE(info.state.estopped);
  EXPECT_EQ(info.state.mode, "idle");
  const nlohmann::json j = BenchInfoToJson(info);
  EXPECT_EQ(j.at("kind"), "sim");
  EXPECT_EQ(j.at("limits").at("pulse_rate_hz"), 33.0);
  EXPECT_EQ(j.at("state").at("busy"), false);
}

TEST(BenchService, AdminReadsAndReplacesTheVirtualSubject) {
  Rig rig;
  EXPECT_EQ(rig.service->GetVirtualSubject(rig.clinician).status().code(),
            api::ErrorCode::kPermissionDenied);
  auto current = rig.service->GetVirtualSubject(rig.admin);
  ASSERT_TRUE(current.ok());
  EXPECT_EQ(*current, VirtualSubjectToJson(DrawVirtualSubject(21)));

  VirtualSubject next = DrawVirtualSubject(22);
  next.name = "replacement";
  EXPECT_EQ(
      rig.service->PutVirtualSubject(rig.clinician, VirtualSubjectToJson(next)).status().code(),
      api::ErrorCode::kPermissionDenied);
  auto put = rig.service->PutVirtualSubject(rig.admin, VirtualSubjectToJson(next));
  ASSERT_TRUE(put.ok()) << put.status().ToString();
  EXPECT_EQ(put->at("name"), "replacement");
  EXPECT_EQ(rig.bench->subject(), next);
  EXPECT_EQ(rig.bench->current()->subject(), next);
  EXPECT_DOUBLE_EQ(rig.bench->Now_s(), 0.0);

  auto audit = storage::AuditLog(*rig.db).List({});
  ASSERT_TRUE(audit.ok());
  ASSERT_EQ(audit->size(), 1u);
  EXPECT_EQ(audit->front().entry.action, "bench.virtual_subject.put");
  EXPECT_EQ(audit->front().entry.user_id, rig.admin.user_id);

  // Invalid JSON: the field is named and the subject stays.
  nlohmann::json bad = VirtualSubjectToJson(next);
  bad["max_tolerated_ma"] = 150.0;
  auto refused = rig.service->PutVirtualSubject(rig.admin, bad);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(refused.status().field(), "max_tolerated_ma");
  EXPECT_EQ(rig.bench->subject(), next);
  auto typo = rig.service->PutVirtualSubject(rig.admin, nlohmann::json::array());
  EXPECT_EQ(typo.status().code(), api::ErrorCode::kInvalidArgument);
}

TEST(BenchService, ADrawSeedReplacesTheSubjectWithTheSeededDraw) {
  Rig rig;
  EXPECT_EQ(rig.service->PutVirtualSubject(rig.clinician, {{"draw_seed", 33}}).status().code(),
            api::ErrorCode::kPermissionDenied);
  auto put = rig.service->PutVirtualSubject(rig.admin, {{"draw_seed", 33}});
  ASSERT_TRUE(put.ok()) << put.status().ToString();
  const VirtualSubject drawn = DrawVirtualSubject(33);
  EXPECT_EQ(rig.bench->subject(), drawn);
  EXPECT_EQ(*put, VirtualSubjectToJson(drawn));
  EXPECT_EQ(put->at("truth"), VirtualSubjectToJson(drawn).at("truth"));
  EXPECT_NE(rig.bench->subject().truth, DrawVirtualSubject(21).truth);
  // A seed parsed from text is unsigned; the largest one is accepted too.
  auto big = rig.service->PutVirtualSubject(
      rig.admin, nlohmann::json::parse(R"({"draw_seed": 18446744073709551615})"));
  ASSERT_TRUE(big.ok()) << big.status().ToString();
  EXPECT_EQ(rig.bench->subject(), DrawVirtualSubject(18446744073709551615ULL));

  auto audit = storage::AuditLog(*rig.db).List({});
  ASSERT_TRUE(audit.ok());
  ASSERT_EQ(audit->size(), 2u);
  bool seen = false;
  for (const auto& row : *audit) {
    EXPECT_EQ(row.entry.action, "bench.virtual_subject.put");
    EXPECT_EQ(row.entry.user_id, rig.admin.user_id);
    seen = seen || row.entry.request_summary == "virtual subject drawn from seed 33, family thesis";
  }
  EXPECT_TRUE(seen);

  // Refusals name the field and leave the subject (and the audit) as it was.
  const auto expect_refused = [&](const nlohmann::json& body, const std::string& field) {
    SCOPED_TRACE(body.dump());
    auto refused = rig.service->PutVirtualSubject(rig.admin, body);
    ASSERT_FALSE(refused.ok());
    EXPECT_EQ(refused.status().code(), api::ErrorCode::kInvalidArgument);
    EXPECT_EQ(refused.status().field(), field);
  };
  expect_refused({{"draw_seed", -1}}, "draw_seed");
  expect_refused({{"draw_seed", 2.5}}, "draw_seed");
  expect_refused(nlohmann::json::parse(R"({"draw_seed": 3.0})"), "draw_seed");
  expect_refused({{"draw_seed", "7"}}, "draw_seed");
  expect_refused({{"draw_seed", nullptr}}, "draw_seed");
  expect_refused({{"draw_seed", 7}, {"fidelity", nlohmann::json::object()}}, "fidelity");
  expect_refused({{"draw_seed", 7}, {"name", "x"}}, "name");
  expect_refused({{"draw_seed", 7}, {"family", "gaussian"}}, "family");
  expect_refused({{"draw_seed", 7}, {"family", 2}}, "family");
  expect_refused({{"draw_seed", 7}, {"family", nullptr}}, "family");
  expect_refused({{"family", "analytic"}}, "draw_seed");
  EXPECT_EQ(rig.bench->subject(), DrawVirtualSubject(18446744073709551615ULL));
  EXPECT_EQ(storage::AuditLog(*rig.db).List({})->size(), 2u);
}

TEST(BenchService, ADrawTakesAFamily) {
  Rig rig;
  auto analytic =
      rig.service->PutVirtualSubject(rig.admin, {{"draw_seed", 8}, {"family", "analytic"}});
  ASSERT_TRUE(analytic.ok()) << analytic.status().ToString();
  EXPECT_EQ(rig.bench->subject(), DrawAnalyticSubject(8));
  EXPECT_EQ(*analytic, VirtualSubjectToJson(DrawAnalyticSubject(8)));
  auto thesis = rig.service->PutVirtualSubject(rig.admin, {{"draw_seed", 8}, {"family", "thesis"}});
  ASSERT_TRUE(thesis.ok()) << thesis.status().ToString();
  EXPECT_EQ(rig.bench->subject(), DrawVirtualSubject(8));
  auto plateau =
      rig.service->PutVirtualSubject(rig.admin, {{"draw_seed", 8}, {"family", "plateau"}});
  ASSERT_TRUE(plateau.ok()) << plateau.status().ToString();
  EXPECT_EQ(rig.bench->subject(), DrawPlateauSubject(8));
  auto audit = storage::AuditLog(*rig.db).List({});
  ASSERT_TRUE(audit.ok());
  bool seen = false;
  for (const auto& row : *audit) {
    seen =
        seen || row.entry.request_summary == "virtual subject drawn from seed 8, family analytic";
  }
  EXPECT_TRUE(seen);
}

TEST(BenchService, TheSubjectCannotChangeDuringARun) {
  Rig rig(1.0);
  storage::SubjectDetails d;
  auto subject = storage::SubjectRepository(*rig.db).Create("S021", d);
  ASSERT_TRUE(subject.ok());
  auto leg = storage::SubjectRepository(*rig.db).AddLeg(subject->id, storage::Side::kLeft);
  ASSERT_TRUE(leg.ok());
  storage::SessionDetails sd;
  sd.date = "2026-02-01";
  auto session = storage::SessionRepository(*rig.db).Create(subject->id, leg->id, sd);
  ASSERT_TRUE(session.ok());
  auto run = rig.runs->Start(rig.clinician, session->id, "tolerance_test", {});
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  EXPECT_TRUE(rig.service->Info().state.busy);
  auto put = rig.service->PutVirtualSubject(rig.admin, VirtualSubjectToJson(DrawVirtualSubject(5)));
  ASSERT_FALSE(put.ok());
  EXPECT_EQ(put.status().code(), api::ErrorCode::kConflict);
  EXPECT_EQ(rig.bench->subject(), DrawVirtualSubject(21));
  ASSERT_TRUE(rig.runs->Cancel(rig.clinician, run->run_id).ok());
  auto view = rig.runs->Wait(run->run_id, 60s);
  ASSERT_TRUE(view.ok());
  EXPECT_EQ(view->state, protocols::RunState::kAborted);
  auto after =
      rig.service->PutVirtualSubject(rig.admin, VirtualSubjectToJson(DrawVirtualSubject(5)));
  EXPECT_TRUE(after.ok()) << after.status().ToString();
}

TEST(BenchService, AHardwareEStopSurvivesASubjectChange) {
  Rig rig;
  rig.bench->HardwareEStop();
  ASSERT_TRUE(
      rig.service->PutVirtualSubject(rig.admin, VirtualSubjectToJson(DrawVirtualSubject(8))).ok());
  EXPECT_TRUE(rig.bench->HardwareEStopped());
  EXPECT_TRUE(rig.service->Info().state.estopped);
  ASSERT_TRUE(rig.runs->ClearEStop(rig.clinician).ok());
  EXPECT_FALSE(rig.bench->HardwareEStopped());
}

TEST(BenchService, ABenchThatIsNotSimulatedHasNoVirtualSubject) {
  Rig rig;
  api::Trial trial;
  trial.SetChannel("t_s", {0.0, 0.005, 0.01});
  trial.SetChannel("angle_deg", {80.0, 80.0, 80.0});
  auto replay = ReplayBench::Create({trial});
  ASSERT_TRUE(replay.ok()) << replay.status().ToString();
  SampleHub hub;
  RunService runs(*rig.db, **replay, hub, {});
  BenchService service(*rig.db, runs, nullptr);
  EXPECT_EQ(service.Info().kind, "replay");
  EXPECT_FALSE(service.Info().simulated);
  auto get = service.GetVirtualSubject(rig.admin);
  ASSERT_FALSE(get.ok());
  EXPECT_EQ(get.status().code(), api::ErrorCode::kConflict);
  EXPECT_EQ(get.status().message(), "not a simulated bench");
  EXPECT_EQ(service.PutVirtualSubject(rig.admin, nlohmann::json::object()).status().code(),
            api::ErrorCode::kConflict);
}

}  // namespace
}  // namespace fesbench::server::services
