// The participant's XML profile (docs/API.md, "DDS"): --dds-profile is applied —
// the participant is created from the file's default participant profile,
// or from a named one — so a QoS and a property written in the XML are the
// participant's. And the IDL's structs are explicitly @final (§12).
#include "api/dds/participant.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include "tests/dds/dds_rig.h"

#ifndef FESBENCH_IDL_FILE
#error "FESBENCH_IDL_FILE must name api/dds/fesbench.idl"
#endif

namespace fesbench::server::dds::testing {
namespace {

std::filesystem::path WriteProfile(const std::filesystem::path& dir, bool is_default) {
  const auto path = dir / (is_default ? "default_profile.xml" : "named_profile.xml");
  std::ofstream out(path);
  out << R"(<?xml version="1.0" encoding="UTF-8"?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <participant profile_name=")"
      << (is_default ? "fesbench_default_under_test" : "fesbench_named_under_test") << "\""
      << (is_default ? R"( is_default_profile="true")" : "") << R"(>
    <rtps>
      <builtin>
        <discovery_config>
          <leaseDuration><sec>)"
      << (is_default ? 9 : 7) << R"(</sec><nanosec>0</nanosec></leaseDuration>
        </discovery_config>
      </builtin>
      <propertiesPolicy>
        <properties>
          <property><name>fesbench.test.marker</name><value>)"
      << (is_default ? "default" : "named") << R"(</value></property>
        </properties>
      </propertiesPolicy>
    </rtps>
  </participant>
</profiles>
)";
  return path;
}

std::string Property(const fdds::DomainParticipantQos& qos, const std::string& name) {
  for (const auto& p : qos.properties().properties()) {
    if (p.name() == name) return p.value();
  }
  return "";
}

TEST(Participant, ANamedProfileOfTheFileGivesItsQosAndProperties) {
  const auto dir = TempDir();
  fesbench::dds::ParticipantOptions options;
  options.domain_id = UniqueDomain();
  options.transport = fesbench::dds::Transport::kUdpLoopback;
  options.profile_file = WriteProfile(dir, false).string();
  options.profile_name = "fesbench_named_under_test";
  options.name = "profile-test";
  auto p = fesbench::dds::Participant::Create(options);
  ASSERT_TRUE(p.ok()) << p.status().ToString();
  const fdds::DomainParticipantQos qos = (*p)->participant()->get_qos();
  EXPECT_EQ(qos.wire_protocol().builtin.discovery_config.leaseDuration.seconds, 7);
  EXPECT_EQ(Property(qos, "fesbench.test.marker"), "named");
  EXPECT_EQ(std::string(qos.name()), "profile-test");
  p->reset();

  options.profile_name = "no_such_profile";
  auto unknown = fesbench::dds::Participant::Create(options);
  ASSERT_FALSE(unknown.ok());
  EXPECT_EQ(unknown.status().code(), api::ErrorCode::kInvalidArgument);
  EXPECT_EQ(unknown.status().field(), "profile_name");
  options.profile_file = (dir / "missing.xml").string();
  options.profile_name.clear();
  EXPECT_EQ(fesbench::dds::Participant::Create(options).status().field(), "profile");
  std::filesystem::remove_all(dir);
}

// What --dds-profile FILE alone does. In a child process: a default profile
// becomes the default of every later participant of the process.
TEST(Participant, TheFilesDefaultProfileIsAppliedWithoutAName) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  const auto dir = TempDir();
  const std::string file = WriteProfile(dir, true).string();
  const int domain = UniqueDomain();
  EXPECT_EXIT(
      {
        fesbench::dds::ParticipantOptions options;
        options.domain_id = domain;
        options.transport = fesbench::dds::Transport::kUdpLoopback;
        options.profile_file = file;
        auto p = fesbench::dds::Participant::Create(options);
        if (!p.ok()) {
          std::fprintf(stderr, "create: %s\n", p.status().ToString().c_str());
          std::_Exit(2);
        }
        const auto qos = (*p)->participant()->get_qos();
        const long lease_s = qos.wire_protocol().builtin.discovery_config.leaseDuration.seconds;
        const std::string marker = Property(qos, "fesbench.test.marker");
        std::fprintf(stderr, "lease %ld s, marker '%s'\n", lease_s, marker.c_str());
        std::_Exit(lease_s == 9 && marker == "default" ? 0 : 1);
      },
      ::testing::ExitedWithCode(0), "lease 9 s, marker 'default'");
  std::filesystem::remove_all(dir);
}

// Every struct says @final, so no vendor's default
// extensibility (appendable in XTypes) can silently stop matching.
TEST(Idl, EveryStructIsExplicitlyFinal) {
  std::ifstream in(FESBENCH_IDL_FILE);
  ASSERT_TRUE(in) << FESBENCH_IDL_FILE;
  std::stringstream text;
  text << in.rdbuf();
  const std::string idl = text.str();
  const std::regex any_struct(R"(\bstruct\s+(\w+)\s*\{)");
  const std::regex final_struct(R"(@final\s+struct\s+(\w+)\s*\{)");
  std::set<std::string> all, final;
  for (auto it = std::sregex_iterator(idl.begin(), idl.end(), any_struct);
       it != std::sregex_iterator(); ++it) {
    all.insert((*it)[1]);
  }
  for (auto it = std::sregex_iterator(idl.begin(), idl.end(), final_struct);
       it != std::sregex_iterator(); ++it) {
    final.insert((*it)[1]);
  }
  EXPECT_GE(all.size(), 8u);
  EXPECT_EQ(final, all);
}

}  // namespace
}  // namespace fesbench::server::dds::testing
