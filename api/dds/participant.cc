#include "api/dds/participant.h"

#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/shared_mem/SharedMemTransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>
#include <time.h>

#include <chrono>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <filesystem>
#include <utility>

#include "api/dds/fesbench.h"
#include "api/dds/fesbenchPubSubTypes.h"

namespace fesbench::dds {

namespace fdds = eprosima::fastdds::dds;
using eprosima::fastrtps::rtps::IPLocator;
using eprosima::fastrtps::rtps::Locator_t;

namespace {

constexpr std::uint32_t kInitialPeersRange = 32;  // participants per host reachable on loopback

void ApplyTransport(Transport transport, fdds::DomainParticipantQos& qos) {
  if (transport == Transport::kBuiltin) return;
  qos.transport().use_builtin_transports = false;
  qos.transport().user_transports.clear();
  if (transport == Transport::kSharedMemory) {
    qos.transport().user_transports.push_back(
        std::make_shared<eprosima::fastdds::rtps::SharedMemTransportDescriptor>());
    return;
  }
  auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
  udp->maxInitialPeersRange = kInitialPeersRange;
  if (transport == Transport::kUdpLoopback) {
    udp->interfaceWhiteList.emplace_back("127.0.0.1");
    Locator_t peer;
    IPLocator::setIPv4(peer, 127, 0, 0, 1);
    qos.wire_protocol().builtin.initialPeersList.push_back(peer);
  }
  qos.transport().user_transports.push_back(udp);
}

// The builtin plugins' properties (Fast DDS "DDS Security" documentation,
// OMG DDS Security 1.1 §9.3.1, §9.4.1); file URIs of absolute paths.
void ApplySecurity(const SecurityFiles& files, fdds::DomainParticipantQos& qos) {
  auto& props = qos.properties().properties();
  const auto set = [&props](const std::string& name, const std::string& value) {
    for (auto& p : props) {
      if (p.name() == name) {
        p.value(value);
        return;
      }
    }
    props.emplace_back(name, value);
  };
  const auto uri = [](const std::string& path) { return "file://" + path; };
  set("dds.sec.auth.plugin", "builtin.PKI-DH");
  set("dds.sec.auth.builtin.PKI-DH.identity_ca", uri(files.identity_ca));
  set("dds.sec.auth.builtin.PKI-DH.identity_certificate", uri(files.identity_certificate));
  set("dds.sec.auth.builtin.PKI-DH.private_key", uri(files.private_key));
  set("dds.sec.access.plugin", "builtin.Access-Permissions");
  set("dds.sec.access.builtin.Access-Permissions.permissions_ca", uri(files.permissions_ca));
  set("dds.sec.access.builtin.Access-Permissions.governance", uri(files.governance));
  set("dds.sec.access.builtin.Access-Permissions.permissions", uri(files.permissions));
  set("dds.sec.crypto.plugin", "builtin.AES-GCM-GMAC");
}

template <class PubSubType>
fdds::Topic* MakeTopic(fdds::DomainParticipant* p, const char* name) {
  fdds::TypeSupport type(new PubSubType());
  if (type.register_type(p) != eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) return nullptr;
  return p->create_topic(name, type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
}

}  // namespace

std::string_view TransportName(Transport transport) {
  switch (transport) {
    case Transport::kBuiltin:
      return "auto";
    case Transport::kSharedMemory:
      return "shm";
    case Transport::kUdp:
      return "udp";
    case Transport::kUdpLoopback:
      return "udp-loopback";
  }
  return "auto";
}

api::Result<Transport> ParseTransport(std::string_view name) {
  for (auto t :
       {Transport::kBuiltin, Transport::kSharedMemory, Transport::kUdp, Transport::kUdpLoopback}) {
    if (TransportName(t) == name) return t;
  }
  return api::Status::InvalidArgument(
      "unknown DDS transport '" + std::string(name) + "' (auto, shm, udp, udp-loopback)",
      "transport");
}

api::Result<SecurityFiles> SecurityFilesIn(const std::string& directory,
                                           const std::string& identity) {
  if (identity.empty() || identity.size() > 64 ||
      identity.find_first_not_of(
          "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-") !=
          std::string::npos) {
    return api::Status::InvalidArgument(
        "a DDS identity name is 1-64 letters, digits, '_' or '-' (got '" + identity + "')",
        "dds-identity");
  }
  std::error_code ec;
  const std::filesystem::path dir = std::filesystem::absolute(directory, ec);
  if (ec || !std::filesystem::is_directory(dir, ec)) {
    return api::Status::InvalidArgument(
        "no DDS security directory " + directory + " (make one with scripts/make-dds-pki.sh)",
        "dds-security");
  }
  SecurityFiles files;
  const std::pair<std::string*, std::string> wanted[] = {
      {&files.identity_ca, "ca.cert.pem"},
      {&files.identity_certificate, identity + ".cert.pem"},
      {&files.private_key, identity + ".key.pem"},
      {&files.governance, "governance.p7s"},
      {&files.permissions, identity + ".permissions.p7s"},
  };
  for (const auto& [field, name] : wanted) {
    const auto path = dir / name;
    if (!std::filesystem::is_regular_file(path, ec)) {
      return api::Status::InvalidArgument(
          "DDS identity '" + identity + "': no " + path.string() +
              " (scripts/make-dds-pki.sh DIR --add NAME --role R makes one)",
          "dds-security");
    }
    *field = path.lexically_normal().string();
  }
  files.permissions_ca = files.identity_ca;
  return files;
}

api::Result<std::unique_ptr<Participant>> Participant::Create(const ParticipantOptions& options) {
  if (options.domain_id < 0 || options.domain_id > 232) {
    return api::Status::InvalidArgument("DDS domain id must be 0-232", "domain");
  }
  using eprosima::fastrtps::types::ReturnCode_t;
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  // The default XML (FASTRTPS_DEFAULT_PROFILES_FILE or ./DEFAULT_FASTRTPS_PROFILES.xml)
  // first, so the factory's default QoS follows the loaded profiles at all.
  factory->load_profiles();
  fdds::DomainParticipantQos qos = factory->get_default_participant_qos();
  if (!options.profile_name.empty() && options.profile_file.empty()) {
    return api::Status::InvalidArgument("a profile name needs a profile file", "profile_name");
  }
  if (!options.profile_file.empty()) {
    if (factory->load_XML_profiles_file(options.profile_file) != ReturnCode_t::RETCODE_OK) {
      return api::Status::InvalidArgument(
          "cannot load Fast DDS XML profile " + options.profile_file, "profile");
    }
    if (options.profile_name.empty()) {
      // Loading a file does not change the factory's default QoS: setting
      // the default to PARTICIPANT_QOS_DEFAULT re-reads the default profile.
      factory->set_default_participant_qos(fdds::PARTICIPANT_QOS_DEFAULT);
      qos = factory->get_default_participant_qos();
    } else if (factory->get_participant_qos_from_profile(options.profile_name, qos) !=
               ReturnCode_t::RETCODE_OK) {
      return api::Status::InvalidArgument(
          "no participant profile '" + options.profile_name + "' in " + options.profile_file,
          "profile_name");
    }
  }
  qos.name(options.name);
  ApplyTransport(options.transport, qos);
  if (options.security) ApplySecurity(*options.security, qos);

  std::unique_ptr<Participant> out(new Participant());
  out->secured_ = options.security.has_value();
  out->participant_ = factory->create_participant(options.domain_id, qos);
  if (!out->participant_ && options.security) {
    return api::Status::InvalidArgument(
        "Fast DDS refused the DDS Security files of " + options.security->identity_certificate +
            ": the certificate and key must match and be signed by the CA, governance and "
            "permissions signed by the permissions CA, the permissions granted to this "
            "certificate's subject and valid now (Fast DDS's log above says which)",
        "dds-security");
  }
  if (!out->participant_)
    return api::Status::Unavailable("Fast DDS could not create a participant");
  auto* p = out->participant_;
  out->publisher_ = p->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  out->subscriber_ = p->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  out->samples_ = MakeTopic<SampleBlockPubSubType>(p, kSamplesTopic);
  out->bench_state_ = MakeTopic<BenchStatePubSubType>(p, kBenchStateTopic);
  out->run_events_ = MakeTopic<RunEventPubSubType>(p, kRunEventsTopic);
  out->parameter_sets_ = MakeTopic<ParameterSetPubSubType>(p, kParameterSetsTopic);
  out->commands_ = MakeTopic<CommandPubSubType>(p, kCommandsTopic);
  out->replies_ = MakeTopic<CommandReplyPubSubType>(p, kRepliesTopic);
  if (!out->publisher_ || !out->subscriber_ || !out->samples_ || !out->bench_state_ ||
      !out->run_events_ || !out->parameter_sets_ || !out->commands_ || !out->replies_) {
    return api::Status::Unavailable("Fast DDS could not create the fesbench topics");
  }
  return out;
}

Participant::~Participant() {
  if (!participant_) return;
  participant_->delete_contained_entities();
  fdds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
}

fdds::DataWriter* Participant::MakeWriter(fdds::Topic* topic, fdds::DataWriterListener* listener) {
  return publisher_->create_datawriter(topic, WriterQosFor(topic->get_name()), listener);
}

fdds::DataReader* Participant::MakeReader(fdds::Topic* topic, fdds::DataReaderListener* listener) {
  return subscriber_->create_datareader(topic, ReaderQosFor(topic->get_name()), listener);
}

namespace {

struct TopicQos {
  bool reliable = true;
  bool transient_local = false;
  int depth = 64;
};

TopicQos QosOf(std::string_view topic) {
  if (topic == kSamplesTopic) return {false, false, 64};
  if (topic == kBenchStateTopic) return {true, true, 1};
  if (topic == kRunEventsTopic) return {true, false, 256};
  if (topic == kParameterSetsTopic) return {true, true, 1};
  // Replies are transient local so a client whose reader matched a moment
  // after the reply was written still gets it (it filters by request_id);
  // commands are volatile: a server never acts on a command sent before it started.
  if (topic == kRepliesTopic) return {true, true, 64};
  return {true, false, 64};  // commands
}

template <class Qos>
void Fill(const TopicQos& t, Qos& qos) {
  qos.reliability().kind =
      t.reliable ? fdds::RELIABLE_RELIABILITY_QOS : fdds::BEST_EFFORT_RELIABILITY_QOS;
  qos.durability().kind =
      t.transient_local ? fdds::TRANSIENT_LOCAL_DURABILITY_QOS : fdds::VOLATILE_DURABILITY_QOS;
  qos.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
  qos.history().depth = t.depth;  // per instance for keyed topics
}

}  // namespace

fdds::DataWriterQos WriterQosFor(std::string_view topic_name) {
  fdds::DataWriterQos qos = fdds::DATAWRITER_QOS_DEFAULT;
  const TopicQos t = QosOf(topic_name);
  Fill(t, qos);
  // A late-joining reliable reader gets the stored samples after the
  // writer's next heartbeat: 100 ms rather than Fast DDS's default 3 s.
  if (t.reliable) qos.reliable_writer_qos().times.heartbeatPeriod = {0, 100000000};
  return qos;
}

fdds::DataReaderQos ReaderQosFor(std::string_view topic_name) {
  fdds::DataReaderQos qos = fdds::DATAREADER_QOS_DEFAULT;
  TopicQos t = QosOf(topic_name);
  // Sample readers keep more than the writer: a reader thread that is
  // descheduled for a while (a busy host) must not overwrite unread blocks.
  if (topic_name == kSamplesTopic) t.depth = 1024;
  Fill(t, qos);
  return qos;
}

long long NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

long long MonotonicNs() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<long long>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

}  // namespace fesbench::dds
