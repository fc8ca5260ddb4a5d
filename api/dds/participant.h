#pragma once

/// @file
/// The fesbench DDS participant (docs/API.md, "DDS"), shared by the server, the
/// DDS monitor, tests and benchmarks: domain id, transport (shared memory,
/// UDP, UDP on loopback only, or Fast DDS's built-in shm+UDP), an optional
/// Fast DDS XML profile, the six topics with their registered types, and
/// the QoS of each topic's writers and readers so every party agrees.
///
/// Topics and types (registered type name = IDL scoped name), QoS:
/// - fesbench/bench/samples, fesbench::dds::SampleBlock: best effort, keep
///   last 64 (readers 1024).
/// - fesbench/bench/state, fesbench::dds::BenchState: reliable, transient
///   local, keep last 1 per bench_id.
/// - fesbench/runs/events, fesbench::dds::RunEvent: reliable, keep last 256.
/// - fesbench/parameter_sets, fesbench::dds::ParameterSet: reliable,
///   transient local, keep last 1 per (subject_id, leg_id).
/// - fesbench/commands, fesbench::dds::Command: reliable, volatile, keep last 64.
/// - fesbench/commands/replies, fesbench::dds::CommandReply: reliable,
///   transient local, keep last 64.

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "api/status.h"

namespace fesbench::dds {

inline constexpr const char* kSamplesTopic = "fesbench/bench/samples";
inline constexpr const char* kBenchStateTopic = "fesbench/bench/state";
inline constexpr const char* kRunEventsTopic = "fesbench/runs/events";
inline constexpr const char* kParameterSetsTopic = "fesbench/parameter_sets";
inline constexpr const char* kCommandsTopic = "fesbench/commands";
inline constexpr const char* kRepliesTopic = "fesbench/commands/replies";

/// How the participant talks.
enum class Transport {
  kBuiltin,       ///< Fast DDS default: shared memory on the host plus UDPv4 on every interface.
  kSharedMemory,  ///< shared memory only (same host); segments in /dev/shm.
  kUdp,           ///< UDPv4 on every interface.
  kUdpLoopback,   ///< UDPv4 on 127.0.0.1 only (discovery by unicast to 127.0.0.1).
};

/// "auto", "shm", "udp", "udp-loopback".
std::string_view TransportName(Transport transport);
/// Parses TransportName's names; kInvalidArgument (field "transport") otherwise.
api::Result<Transport> ParseTransport(std::string_view name);

/// DDS Security (OMG DDS Security 1.1, Fast DDS's builtin plugins
/// builtin.PKI-DH, builtin.Access-Permissions, builtin.AES-GCM-GMAC): the
/// files of one identity of a lab PKI. With these set, the participant
/// authenticates every peer against the CA, encrypts what governance says
/// (scripts/make-dds-pki.sh: discovery, liveliness and data, every topic),
/// and may publish and subscribe only what its signed permissions grant.
struct SecurityFiles {
  std::string identity_ca;           ///< CA certificate (PEM) that signed every identity.
  std::string identity_certificate;  ///< this participant's certificate (PEM).
  std::string private_key;           ///< its private key (PEM).
  std::string permissions_ca;        ///< CA certificate that signed governance and permissions.
  std::string governance;            ///< signed governance (S/MIME).
  std::string permissions;           ///< this identity's signed permissions (S/MIME).
};

/// The files of identity `identity` in a directory made by
/// scripts/make-dds-pki.sh (ca.cert.pem, governance.p7s, NAME.cert.pem,
/// NAME.key.pem, NAME.permissions.p7s), as absolute paths. kInvalidArgument
/// naming the missing file (field "dds-security") or a bad identity name
/// (field "dds-identity").
api::Result<SecurityFiles> SecurityFilesIn(const std::string& directory,
                                           const std::string& identity);

struct ParticipantOptions {
  int domain_id = 0;  ///< 0–232.
  Transport transport = Transport::kBuiltin;
  /// A Fast DDS XML profile file. The participant is created from its
  /// participant profile `profile_name`, or, when that is empty, from its
  /// default participant profile (is_default_profile="true"): QoS, transports
  /// and properties (e.g. DDS Security) as written. The transport above is
  /// applied on top unless kBuiltin; the participant name is `name`.
  std::string profile_file;
  std::string profile_name;       ///< a participant profile of profile_file; "" = its default.
  std::string name = "fesbench";  ///< participant name (seen by DDS tools).
  /// Secured DDS when set (on top of the profile's properties); unsecured otherwise.
  std::optional<SecurityFiles> security;
};

/// A participant with one publisher, one subscriber and the six topics.
/// Destroying it deletes every entity it contains (writers/readers too).
class Participant {
 public:
  /// kInvalidArgument for a bad domain id, an unloadable profile file
  /// (field "profile"), an unknown profile name (field "profile_name") or
  /// security files Fast DDS refuses (field "dds-security": a certificate
  /// not signed by the CA, an unsigned or wrongly signed governance or
  /// permissions document, permissions for another subject);
  /// kUnavailable if Fast DDS cannot create the participant otherwise.
  static api::Result<std::unique_ptr<Participant>> Create(const ParticipantOptions& options);
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  eprosima::fastdds::dds::DomainParticipant* participant() { return participant_; }
  bool secured() const { return secured_; }
  eprosima::fastdds::dds::Publisher* publisher() { return publisher_; }
  eprosima::fastdds::dds::Subscriber* subscriber() { return subscriber_; }
  eprosima::fastdds::dds::Topic* samples() { return samples_; }
  eprosima::fastdds::dds::Topic* bench_state() { return bench_state_; }
  eprosima::fastdds::dds::Topic* run_events() { return run_events_; }
  eprosima::fastdds::dds::Topic* parameter_sets() { return parameter_sets_; }
  eprosima::fastdds::dds::Topic* commands() { return commands_; }
  eprosima::fastdds::dds::Topic* replies() { return replies_; }

  /// A writer / reader on `topic` with the topic's QoS (WriterQosFor /
  /// ReaderQosFor); nullptr if Fast DDS refuses (with DDS Security: also
  /// when the identity's permissions do not grant it).
  eprosima::fastdds::dds::DataWriter* MakeWriter(
      eprosima::fastdds::dds::Topic* topic,
      eprosima::fastdds::dds::DataWriterListener* listener = nullptr);
  eprosima::fastdds::dds::DataReader* MakeReader(
      eprosima::fastdds::dds::Topic* topic,
      eprosima::fastdds::dds::DataReaderListener* listener = nullptr);

 private:
  Participant() = default;
  eprosima::fastdds::dds::DomainParticipant* participant_ = nullptr;
  bool secured_ = false;
  eprosima::fastdds::dds::Publisher* publisher_ = nullptr;
  eprosima::fastdds::dds::Subscriber* subscriber_ = nullptr;
  eprosima::fastdds::dds::Topic* samples_ = nullptr;
  eprosima::fastdds::dds::Topic* bench_state_ = nullptr;
  eprosima::fastdds::dds::Topic* run_events_ = nullptr;
  eprosima::fastdds::dds::Topic* parameter_sets_ = nullptr;
  eprosima::fastdds::dds::Topic* commands_ = nullptr;
  eprosima::fastdds::dds::Topic* replies_ = nullptr;
};

/// The QoS of writers / readers on the topic named `topic_name` (the table above).
eprosima::fastdds::dds::DataWriterQos WriterQosFor(std::string_view topic_name);
eprosima::fastdds::dds::DataReaderQos ReaderQosFor(std::string_view topic_name);

/// Nanoseconds since the Unix epoch (system clock) and CLOCK_MONOTONIC.
long long NowNs();
long long MonotonicNs();

}  // namespace fesbench::dds
