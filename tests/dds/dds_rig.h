#pragma once
// A test rig for the DDS front end: services on a temporary database, a
// DdsServer and client participants on UDP loopback with a domain id unique
// to the test process (parallel ctest runs do not meet).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <optional>
#include <thread>

#include "api/dds/fesbench.h"
#include "api/dds/participant.h"
#include "model/parameter_set.h"
#include "server/bench/virtual_subject.h"
#include "server/dds/dds_server.h"
#include "server/services/bench_service.h"
#include "server/services/commands.h"
#include "server/services/run_service.h"
#include "storage/parameter_sets.h"
#include "storage/sessions.h"
#include "storage/subjects.h"
#include "storage/users.h"

namespace fesbench::server::dds::testing {

namespace wire = fesbench::dds;
namespace fdds = eprosima::fastdds::dds;
using namespace std::chrono_literals;
using eprosima::fastrtps::types::ReturnCode_t;
using services::Actor;

inline constexpr auto kWait = 20s;  // only reached if something is broken

// A domain id per test, unique across processes running at once.
inline int UniqueDomain() {
  static std::atomic<int> counter{0};
  return 1 + static_cast<int>((static_cast<unsigned>(::getpid()) * 4u + counter++) % 230u);
}

inline std::filesystem::path TempDir() {
  static std::atomic<int> counter{0};
  const auto dir = std::filesystem::temp_directory_path() /
                   ("fesbench_dds_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

inline const protocols::ParameterValues kShortTolerance = {
    {"settle_s", 0.2}, {"start_ma", 0.0}, {"rate_ma_per_s", 5.0}, {"ceiling_ma", 3.0}};

/// Database (users with tokens, a subject with two legs, a session), a
/// simulated bench, the run and command services and the DDS server.
struct Rig {
  explicit Rig(double time_scale) : dir(TempDir()), domain(UniqueDomain()) {
    storage::DatabaseOptions dbo;
    dbo.path = (dir / "fesbench.db").string();
    dbo.synchronous = storage::Synchronous::kNormal;
    auto opened = storage::Database::Open(dbo);
    EXPECT_TRUE(opened.ok()) << opened.status().ToString();
    db = std::move(opened).value();

    storage::UserRepository users(*db);
    clinician = MakeUser(users, "cora", storage::Role::kClinician, &clinician_token);
    analyst = MakeUser(users, "ana", storage::Role::kAnalyst, &analyst_token);

    vs = DrawVirtualSubject(11);
    storage::SubjectDetails details;
    details.weight_kg = vs.anthropometrics.body_mass_kg;
    details.height_cm = vs.anthropometrics.height_m * 100.0;
    details.shank_length_cm = vs.anthropometrics.shank_length_m * 100.0;
    storage::SubjectRepository subjects(*db);
    auto subject = subjects.Create("S011", details);
    EXPECT_TRUE(subject.ok()) << subject.status().ToString();
    subject_id = subject->id;
    left_leg = subjects.AddLeg(subject_id, storage::Side::kLeft)->id;
    right_leg = subjects.AddLeg(subject_id, storage::Side::kRight)->id;
    storage::SessionDetails sd;
    sd.date = "2026-01-15";
    sd.accelerometer_placement = "shank, 28 cm below the knee";
    sd.threshold_ma = vs.threshold_ma;
    sd.max_tolerated_ma = vs.max_tolerated_ma;
    session_id = storage::SessionRepository(*db).Create(subject_id, right_leg, sd)->id;

    SimulatedBenchOptions bo;
    bo.time_scale = time_scale;
    bo.seed = 3;
    bench = SwappableSimulatedBench::Create(vs, bo).value();
    services::RunServiceConfig config;
    config.time_scale = time_scale;
    config.arm_watchdog = false;
    runs = std::make_unique<services::RunService>(*db, *bench, hub, config);
    commands = std::make_unique<services::CommandService>(*db, *runs, "dds");
    set_events = std::make_unique<services::ParameterSetEvents>(*db, hub);
  }
  ~Rig() {
    if (server) server->Stop();
    runs.reset();
    set_events.reset();
    db.reset();
    std::filesystem::remove_all(dir);
  }

  static Actor MakeUser(storage::UserRepository& users, const char* name, storage::Role role,
                        std::string* token) {
    auto u = users.CreateUser(name, role);
    EXPECT_TRUE(u.ok()) << u.status().ToString();
    auto t = users.IssueToken(u->id, "test");
    EXPECT_TRUE(t.ok());
    *token = t->token;
    return Actor{u->id, name, role};
  }

  std::int64_t StoreSet(std::int64_t leg_id, double pole_per_s) {
    storage::NewParameterSet set;
    set.subject_id = subject_id;
    set.leg_id = leg_id;
    set.params = model::ExampleParameterSet();
    set.params.contraction.pole_per_s = pole_per_s;
    auto stored = storage::ParameterSetRepository(*db).Insert(set);
    EXPECT_TRUE(stored.ok()) << stored.status().ToString();
    return stored.ok() ? stored->id : 0;
  }

  void StartServer(std::optional<wire::SecurityFiles> security = std::nullopt) {
    DdsServerOptions options;
    options.participant.security = std::move(security);
    options.participant.domain_id = domain;
    options.participant.transport = wire::Transport::kUdpLoopback;
    options.participant.name = "fesbench-test-server";
    options.bench_id = "bench-under-test";
    auto started = DdsServer::Start(options, *db, *runs, hub, *commands);
    ASSERT_TRUE(started.ok()) << started.status().ToString();
    server = std::move(*started);
  }

  std::unique_ptr<wire::Participant> Client(
      std::optional<wire::SecurityFiles> security = std::nullopt) {
    wire::ParticipantOptions options;
    options.security = std::move(security);
    options.domain_id = domain;
    options.transport = wire::Transport::kUdpLoopback;
    options.name = "fesbench-test-client";
    auto p = wire::Participant::Create(options);
    EXPECT_TRUE(p.ok()) << p.status().ToString();
    return p.ok() ? std::move(*p) : nullptr;
  }

  std::filesystem::path dir;
  int domain;
  std::unique_ptr<storage::Database> db;
  Actor clinician, analyst;
  std::string clinician_token, analyst_token;
  VirtualSubject vs;
  std::int64_t subject_id = 0, left_leg = 0, right_leg = 0, session_id = 0;
  std::unique_ptr<SwappableSimulatedBench> bench;
  services::SampleHub hub;
  std::unique_ptr<services::ParameterSetEvents> set_events;
  std::unique_ptr<services::RunService> runs;
  std::unique_ptr<services::CommandService> commands;
  std::unique_ptr<DdsServer> server;
};

template <class T>
std::vector<T> TakeAll(fdds::DataReader* reader) {
  std::vector<T> out;
  T value;
  fdds::SampleInfo info;
  while (reader->take_next_sample(&value, &info) == ReturnCode_t::RETCODE_OK) {
    if (info.valid_data) out.push_back(value);
  }
  return out;
}

inline bool WaitMatched(fdds::DataWriter* writer) {
  const auto until = std::chrono::steady_clock::now() + kWait;
  fdds::PublicationMatchedStatus status;
  while (std::chrono::steady_clock::now() < until) {
    writer->get_publication_matched_status(status);
    if (status.current_count > 0) return true;
    std::this_thread::sleep_for(10ms);
  }
  return false;
}

inline bool WaitMatched(fdds::DataReader* reader) {
  const auto until = std::chrono::steady_clock::now() + kWait;
  fdds::SubscriptionMatchedStatus status;
  while (std::chrono::steady_clock::now() < until) {
    reader->get_subscription_matched_status(status);
    if (status.current_count > 0) return true;
    std::this_thread::sleep_for(10ms);
  }
  return false;
}

/// A command client: writer on fesbench/commands, reader on the replies.
struct CommandClient {
  explicit CommandClient(wire::Participant& p)
      : writer(p.MakeWriter(p.commands())), replies(p.MakeReader(p.replies())) {
    EXPECT_TRUE(WaitMatched(writer));
    EXPECT_TRUE(WaitMatched(replies));
  }
  wire::CommandReply Send(wire::Command command) {
    command.request_id("req-" + std::to_string(++next_id));
    writer->write(&command);
    const auto until = std::chrono::steady_clock::now() + kWait;
    while (std::chrono::steady_clock::now() < until) {
      replies->wait_for_unread_message(eprosima::fastrtps::Duration_t(0, 50000000));
      for (const auto& reply : TakeAll<wire::CommandReply>(replies)) {
        if (reply.request_id() == command.request_id()) return reply;
      }
    }
    ADD_FAILURE() << "no reply to " << command.request_id();
    return {};
  }
  fdds::DataWriter* writer;
  fdds::DataReader* replies;
  int next_id = 0;
};

inline wire::Command MakeCommand(wire::CommandKind kind, const std::string& token) {
  wire::Command c;
  c.kind(kind);
  c.token(token);
  return c;
}

}  // namespace fesbench::server::dds::testing
