#pragma once

/// @file
/// The server's DDS front end (docs/API.md, "DDS"): a second transport over the
/// same services as HTTP. It publishes, from a SampleHub subscription and
/// the RunService's state, every run's sample blocks, run events and the
/// bench state, and from storage each new parameter set keyed by subject and
/// leg (the latest of every leg at start, then every new version, polled);
/// it answers commands (e-stop, start, cancel, heartbeat) through the
/// CommandService, the same RunService calls, interlocks and audit log as
/// HTTP, replying with the request id, outcome and reason.
///
/// Threads: one forwards hub items (samples, run events), one publishes the
/// bench state when it changes and polls parameter sets, one serves
/// commands. Stop() (or the destructor) joins them and deletes the
/// participant; nothing is left behind on a clean exit (see the README for
/// shared memory after a SIGKILL).

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>

#include "api/dds/participant.h"
#include "api/status.h"
#include "server/services/commands.h"
#include "server/services/run_service.h"
#include "server/services/sample_hub.h"
#include "storage/database.h"
#include "storage/parameter_sets.h"

namespace fesbench::server::dds {

struct DdsServerOptions {
  fesbench::dds::ParticipantOptions participant;
  std::string bench_id;             ///< key of this bench's state; default: host name.
  double state_check_s = 0.05;      ///< how often the bench state is compared and republished.
  std::size_t hub_capacity = 8192;  ///< items queued for the forwarding thread.
};

/// Counters for tests and logs.
struct DdsServerStats {
  std::uint64_t sample_blocks = 0;
  std::uint64_t run_events = 0;
  std::uint64_t bench_states = 0;
  std::uint64_t parameter_sets = 0;
  std::uint64_t commands = 0;
  std::uint64_t hub_dropped = 0;
};

class DdsServer {
 public:
  /// Creates the participant, writers and command reader and starts the
  /// threads. db, runs, hub and commands must outlive the DdsServer.
  /// Errors from Participant::Create; kUnavailable if an entity cannot be made.
  static api::Result<std::unique_ptr<DdsServer>> Start(const DdsServerOptions& options,
                                                       storage::Database& db,
                                                       services::RunService& runs,
                                                       services::SampleHub& hub,
                                                       services::CommandService& commands);
  /// Stop().
  ~DdsServer();
  DdsServer(const DdsServer&) = delete;
  DdsServer& operator=(const DdsServer&) = delete;

  /// Stops the threads and deletes the participant. Idempotent.
  void Stop();
  const std::string& bench_id() const { return options_.bench_id; }
  DdsServerStats stats() const;

 private:
  DdsServer(const DdsServerOptions& options, storage::Database& db, services::RunService& runs,
            services::SampleHub& hub, services::CommandService& commands);
  api::Status Init();
  void ForwardLoop();
  void HousekeepingLoop();
  void CommandLoop();
  void PublishItem(const services::HubItem& item);
  void PublishStateIfChanged(bool force);
  /// The latest set of every leg (at start, for late joiners).
  void PublishLatestParameterSets();
  /// One stored set (a kParameterSet hub item), unless already published.
  void PublishParameterSet(const storage::StoredParameterSet& set);
  void Wake();

  DdsServerOptions options_;
  storage::Database& db_;
  services::RunService& runs_;
  services::SampleHub& hub_;
  services::CommandService& commands_;

  std::unique_ptr<fesbench::dds::Participant> participant_;
  eprosima::fastdds::dds::DataWriter* samples_ = nullptr;
  eprosima::fastdds::dds::DataWriter* state_ = nullptr;
  eprosima::fastdds::dds::DataWriter* events_ = nullptr;
  eprosima::fastdds::dds::DataWriter* parameter_sets_ = nullptr;
  eprosima::fastdds::dds::DataWriter* replies_ = nullptr;
  eprosima::fastdds::dds::DataReader* commands_reader_ = nullptr;
  std::unique_ptr<services::Subscription> subscription_;

  // Forwarding thread only.
  std::int64_t block_run_id_ = 0;
  std::uint64_t block_seq_ = 0;
  // Start, then the forwarding thread only: the id of the newest set
  // published per (subject, leg).
  /// Per (subject, leg): the set last published and the leg's approved set then.
  std::map<std::pair<std::int64_t, std::int64_t>, std::pair<std::int64_t, std::int64_t>>
      published_sets_;
  // Housekeeping thread only.
  std::string last_state_;

  std::atomic<bool> stop_{false};
  std::mutex wake_mu_;
  std::condition_variable wake_cv_;
  bool wake_ = false;
  mutable std::mutex stats_mu_;
  DdsServerStats stats_;
  std::thread forward_thread_, housekeeping_thread_, command_thread_;
};

}  // namespace fesbench::server::dds
