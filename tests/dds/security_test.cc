// Secured DDS (README, "Secured DDS"): a lab PKI made at test time by
// scripts/make-dds-pki.sh; a secured server and monitor work (bench state,
// parameter sets, e-stop), a participant without security or with an
// identity of another CA sees nothing and cannot command, a viewer may
// read but not publish commands, and tampered or missing files are refused
// with the field named.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include "clients/dds_monitor/monitor.h"
#include "tests/dds/dds_rig.h"

namespace fesbench::server::dds::testing {
namespace {

// How long an unsecured peer gets to match after the secured one did.
constexpr auto kNoMatchWindow = 3s;

std::filesystem::path MakePki(const std::filesystem::path& dir) {
  const std::string cmd = std::string(FESBENCH_PKI_SCRIPT) + " " + dir.string() + " >/dev/null";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
  return dir;
}

wire::SecurityFiles Identity(const std::filesystem::path& pki, const std::string& name) {
  auto files = wire::SecurityFilesIn(pki.string(), name);
  EXPECT_TRUE(files.ok()) << files.status().ToString();
  return files.ok() ? *files : wire::SecurityFiles{};
}

dds_monitor::MonitorOptions MonitorOn(int domain, std::optional<wire::SecurityFiles> security,
                                      double timeout_s) {
  dds_monitor::MonitorOptions o;
  o.participant.domain_id = domain;
  o.participant.transport = wire::Transport::kUdpLoopback;
  o.participant.security = std::move(security);
  o.timeout_s = timeout_s;
  return o;
}

bool MatchesWithin(fdds::DataReader* reader, std::chrono::milliseconds window) {
  const auto until = std::chrono::steady_clock::now() + window;
  fdds::SubscriptionMatchedStatus status;
  while (std::chrono::steady_clock::now() < until) {
    reader->get_subscription_matched_status(status);
    if (status.current_count > 0) return true;
    std::this_thread::sleep_for(20ms);
  }
  return false;
}

class SecuredDds : public ::testing::Test {
 protected:
  void SetUp() override { pki_ = MakePki(rig_.dir / "pki"); }
  Rig rig_{0.0};
  std::filesystem::path pki_;
};

TEST_F(SecuredDds, ASecuredMonitorReadsTheServerAndEStopsIt) {
  const std::int64_t set_id = rig_.StoreSet(rig_.left_leg, 23.0);
  rig_.StartServer(Identity(pki_, "server"));
  const auto options = MonitorOn(rig_.domain, Identity(pki_, "operator"), 20.0);

  std::ostringstream benches;
  auto n = dds_monitor::ListBenches(options, benches);
  ASSERT_TRUE(n.ok()) << n.status().ToString();
  EXPECT_EQ(*n, 1);
  std::ostringstream set;
  ASSERT_TRUE(dds_monitor::ShowParameterSet(options, rig_.subject_id, rig_.left_leg, set).ok());
  EXPECT_NE(set.str().find("parameter set " + std::to_string(set_id)), std::string::npos);

  std::ostringstream latched;
  const api::Status st =
      dds_monitor::SendEStop(options, rig_.analyst_token, "bench-under-test", latched);
  ASSERT_TRUE(st.ok()) << st.ToString();
  EXPECT_TRUE(rig_.runs->State().estopped);
}

TEST_F(SecuredDds, AnUnsecuredParticipantOrAnotherCasIdentitySeesNothingAndCannotCommand) {
  rig_.StartServer(Identity(pki_, "server"));
  // The secured viewer matches: discovery works on this domain.
  auto viewer = rig_.Client(Identity(pki_, "viewer"));
  ASSERT_NE(viewer, nullptr);
  fdds::DataReader* seen = viewer->MakeReader(viewer->bench_state());
  ASSERT_NE(seen, nullptr);
  ASSERT_TRUE(WaitMatched(seen));
  seen->wait_for_unread_message(eprosima::fastrtps::Duration_t(20, 0));
  EXPECT_FALSE(TakeAll<wire::BenchState>(seen).empty());

  const auto other_pki = MakePki(rig_.dir / "other-pki");
  for (std::optional<wire::SecurityFiles> security :
       {std::optional<wire::SecurityFiles>{}, std::optional(Identity(other_pki, "operator"))}) {
    SCOPED_TRACE(security ? "identity of another CA" : "no security");
    auto outsider = rig_.Client(security);
    ASSERT_NE(outsider, nullptr);
    fdds::DataReader* state = outsider->MakeReader(outsider->bench_state());
    fdds::DataReader* samples = outsider->MakeReader(outsider->samples());
    fdds::DataWriter* commands = outsider->MakeWriter(outsider->commands());
    ASSERT_TRUE(state && samples && commands);
    EXPECT_FALSE(MatchesWithin(state, kNoMatchWindow));
    fdds::PublicationMatchedStatus pub;
    commands->get_publication_matched_status(pub);
    EXPECT_EQ(pub.current_count, 0);
    wire::Command estop = MakeCommand(wire::CommandKind::CMD_ESTOP, rig_.analyst_token);
    estop.request_id("outsider");
    commands->write(&estop);
    std::this_thread::sleep_for(500ms);
    EXPECT_TRUE(TakeAll<wire::BenchState>(state).empty());
    EXPECT_FALSE(rig_.runs->State().estopped);
    // The monitor says so plainly: no server found.
    std::ostringstream out;
    EXPECT_EQ(dds_monitor::ListBenches(MonitorOn(rig_.domain, security, 1.0), out).status().code(),
              api::ErrorCode::kUnavailable);
  }
}

TEST_F(SecuredDds, AViewerReadsButMayNotPublishCommands) {
  rig_.StartServer(Identity(pki_, "server"));
  auto viewer = rig_.Client(Identity(pki_, "viewer"));
  ASSERT_NE(viewer, nullptr);
  EXPECT_EQ(viewer->MakeWriter(viewer->commands()), nullptr);
  EXPECT_NE(viewer->MakeReader(viewer->samples()), nullptr);

  std::ostringstream out;
  const api::Status st = dds_monitor::SendEStop(
      MonitorOn(rig_.domain, Identity(pki_, "viewer"), 5.0), rig_.analyst_token, "", out);
  EXPECT_EQ(st.code(), api::ErrorCode::kPermissionDenied) << st.ToString();
  EXPECT_NE(st.message().find("role 'operator'"), std::string::npos) << st.message();
  EXPECT_FALSE(rig_.runs->State().estopped);
}

TEST_F(SecuredDds, AServerWithAClientIdentityIsRefusedNamingTheIdentity) {
  DdsServerOptions options;
  options.participant.domain_id = rig_.domain;
  options.participant.transport = wire::Transport::kUdpLoopback;
  options.participant.security = Identity(pki_, "operator");
  auto started = DdsServer::Start(options, *rig_.db, *rig_.runs, rig_.hub, *rig_.commands);
  ASSERT_FALSE(started.ok());
  EXPECT_EQ(started.status().field(), "dds-identity");
}

TEST_F(SecuredDds, MissingOrTamperedFilesAreRefusedWithTheFieldNamed) {
  EXPECT_EQ(wire::SecurityFilesIn((rig_.dir / "nowhere").string(), "server").status().field(),
            "dds-security");
  EXPECT_EQ(wire::SecurityFilesIn(pki_.string(), "../server").status().field(), "dds-identity");
  auto missing = wire::SecurityFilesIn(pki_.string(), "nobody");
  EXPECT_EQ(missing.status().field(), "dds-security");
  EXPECT_NE(missing.status().message().find("nobody.cert.pem"), std::string::npos);

  // Widen the viewer's own permissions by editing the signed document: the
  // signature no longer verifies and the participant is refused.
  const auto path = pki_ / "viewer.permissions.p7s";
  std::stringstream text;
  text << std::ifstream(path).rdbuf();
  std::string doc = text.str();
  const auto at = doc.find("<subscribe>");
  ASSERT_NE(at, std::string::npos);
  doc.insert(at, "<publish><topics><topic>fesbench/commands</topic></topics></publish>\n");
  std::ofstream(path, std::ios::trunc) << doc;
  wire::ParticipantOptions options;
  options.domain_id = rig_.domain;
  options.transport = wire::Transport::kUdpLoopback;
  options.security = Identity(pki_, "viewer");
  auto refused = wire::Participant::Create(options);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().field(), "dds-security");
}

}  // namespace
}  // namespace fesbench::server::dds::testing
