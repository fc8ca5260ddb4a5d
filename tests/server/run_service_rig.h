#pragma once

// RunService's test rig: a temporary database with users, a subject, a leg
// and a session, a simulated bench with a seeded virtual subject, a hub and
// the service; a subscriber's view of a run.

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "server/bench/virtual_subject.h"
#include "server/services/bench_service.h"
#include "server/services/run_service.h"
#include "server/services/sample_hub.h"
#include "storage/subjects.h"
#include "storage/users.h"
#include "tests/support/manual_clock.h"

namespace fesbench::server::services::test {

using namespace std::chrono_literals;
using protocols::RunState;

inline constexpr auto kWait = 120s;  // only reached if something hangs

inline std::filesystem::path TempDir() {
  static std::atomic<int> counter{0};
  const auto dir =
      std::filesystem::temp_directory_path() /
      ("fesbench_runsvc_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

struct RigOptions {
  double time_scale = 0.0;
  bool arm_watchdog = false;
  bool wall_clock_is_bench_time = false;
  bool with_limits = true;  // the session records threshold and max tolerated
  /// > 0: what the subject on the bench now tolerates, mA (it signals the
  /// tolerance test's limit there); 0: the drawn max tolerated, as recorded.
  double subject_tolerates_ma = 0.0;
};

/// A database with users, a subject, a leg and a session, a simulated bench
/// with a seeded virtual subject, a hub and the service.
struct Rig {
  explicit Rig(RigOptions o = {}) : options(o), dir(TempDir()) {
    storage::DatabaseOptions dbo;
    dbo.path = (dir / "fesbench.db").string();
    dbo.synchronous = storage::Synchronous::kNormal;
    auto opened = storage::Database::Open(dbo);
    EXPECT_TRUE(opened.ok()) << opened.status().ToString();
    db = std::move(opened).value();

    storage::UserRepository users(*db);
    clinician = Make(users, "cora", storage::Role::kClinician, Role::kClinician);
    analyst = Make(users, "ana", storage::Role::kAnalyst, Role::kAnalyst);
    admin = Make(users, "adam", storage::Role::kAdmin, Role::kAdmin);

    vs = DrawVirtualSubject(11);
    storage::SubjectDetails details;
    details.weight_kg = vs.anthropometrics.body_mass_kg;
    details.height_cm = vs.anthropometrics.height_m * 100.0;
    details.shank_length_cm = vs.anthropometrics.shank_length_m * 100.0;
    storage::SubjectRepository subjects(*db);
    auto subject = subjects.Create("S011", details);
    EXPECT_TRUE(subject.ok()) << subject.status().ToString();
    subject_id = subject->id;
    auto leg = subjects.AddLeg(subject_id, storage::Side::kRight);
    EXPECT_TRUE(leg.ok());
    leg_id = leg->id;
    storage::SessionDetails sd;
    sd.date = "2026-01-15";
    sd.accelerometer_placement = "shank, 28 cm below the knee";
    if (o.with_limits) {
      sd.threshold_ma = vs.threshold_ma;
      sd.max_tolerated_ma = vs.max_tolerated_ma;
    }
    auto session = storage::SessionRepository(*db).Create(subject_id, leg_id, sd);
    EXPECT_TRUE(session.ok()) << session.status().ToString();
    session_id = session->id;

    SimulatedBenchOptions bo;
    bo.time_scale = o.time_scale;
    bo.seed = 3;
    bo.on_control_step = [this](double t_s) {
      if (hook) hook(t_s);
    };
    VirtualSubject on_bench = vs;
    if (o.subject_tolerates_ma > 0.0) on_bench.max_tolerated_ma = o.subject_tolerates_ma;
    bench = SwappableSimulatedBench::Create(on_bench, bo).value();

    config.time_scale = o.time_scale;
    config.arm_watchdog = o.arm_watchdog;
    if (o.wall_clock_is_bench_time) {
      bench_time =
          std::make_unique<::fesbench::testing::ReadingClock>([this] { return bench->Now_s(); });
      config.clock = bench_time.get();
    }
    config.log = [this](std::string_view m) {
      std::lock_guard lock(log_mu);
      logs.emplace_back(m);
    };
    service = std::make_unique<RunService>(*db, *bench, hub, config);
  }
  ~Rig() {
    service.reset();
    db.reset();
    std::filesystem::remove_all(dir);
  }

  static Actor Make(storage::UserRepository& users, const char* name, storage::Role role,
                    Role service_role) {
    auto u = users.CreateUser(name, role);
    EXPECT_TRUE(u.ok()) << u.status().ToString();
    return Actor{u.ok() ? u->id : 0, name, service_role};
  }

  /// The plan the service will run (same context), to compare with.
  protocols::Plan PlanFor(const std::string& protocol, const protocols::ParameterValues& values) {
    auto context = LoadSessionContext(*db, session_id, bench->limits());
    EXPECT_TRUE(context.ok()) << context.status().ToString();
    auto plan = protocols::MakePlan(protocol, values, context->subject);
    EXPECT_TRUE(plan.ok()) << plan.status().ToString();
    return *plan;
  }

  std::vector<std::string> AuditActions() {
    storage::AuditQuery q;
    auto entries = storage::AuditLog(*db).List(q);
    EXPECT_TRUE(entries.ok());
    std::vector<storage::AuditEntry> sorted = *entries;
    std::sort(sorted.begin(), sorted.end(),
              [](const auto& a, const auto& b) { return a.id < b.id; });
    std::vector<std::string> out;
    for (const auto& e : sorted) out.push_back(e.entry.action);
    return out;
  }

  RigOptions options;
  std::filesystem::path dir;
  std::unique_ptr<storage::Database> db;
  Actor clinician, analyst, admin;
  VirtualSubject vs;
  std::int64_t subject_id = 0, leg_id = 0, session_id = 0;
  std::function<void(double)> hook;  // set before a run starts only
  std::unique_ptr<SwappableSimulatedBench> bench;
  std::unique_ptr<::fesbench::testing::ReadingClock> bench_time;  // wall_clock_is_bench_time
  SampleHub hub;
  RunServiceConfig config;
  std::unique_ptr<RunService> service;
  std::mutex log_mu;
  std::vector<std::string> logs;
};

/// What a subscriber saw of one run.
struct Stream {
  std::vector<HubItemPtr> items;
  std::map<int, std::size_t> samples_per_trial;
  std::uint64_t samples = 0;
  bool in_order = true;  // first_sample contiguous, t_s increasing within a trial
  bool ended = false;
  std::uint64_t dropped = 0;
};

inline Stream Read(Subscription& sub) {
  Stream s;
  std::uint64_t last_seq = 0;
  std::map<int, double> last_t;
  while (HubItemPtr item = sub.Next(kWait)) {
    if (item->seq <= last_seq && last_seq != 0) s.in_order = false;
    last_seq = item->seq;
    s.items.push_back(item);
    if (item->kind == HubItem::Kind::kSamples) {
      if (item->first_sample != s.samples) s.in_order = false;
      for (double t : item->samples.t_s) {
        const auto it = last_t.find(item->samples.trial);
        if (it != last_t.end() && !(t > it->second)) s.in_order = false;
        last_t[item->samples.trial] = t;
      }
      s.samples += item->samples.t_s.size();
      s.samples_per_trial[item->samples.trial] += item->samples.t_s.size();
    }
    if (item->kind == HubItem::Kind::kEnd) {
      s.ended = true;
      break;
    }
  }
  s.dropped = sub.dropped();
  return s;
}

/// Polls until the run is running (or over); a run is e-stopped while
/// running, not while still queued.
inline void WaitRunning(RunService& service, std::int64_t run_id) {
  const auto deadline = std::chrono::steady_clock::now() + kWait;
  while (std::chrono::steady_clock::now() < deadline) {
    auto v = service.Get(run_id);
    if (!v.ok() || v->state != RunState::kQueued) return;
    std::this_thread::sleep_for(1ms);
  }
}

inline const protocols::ParameterValues kShortTolerance = {
    {"settle_s", 0.2}, {"start_ma", 0.0}, {"rate_ma_per_s", 5.0}, {"ceiling_ma", 3.0}};

}  // namespace fesbench::server::services::test
