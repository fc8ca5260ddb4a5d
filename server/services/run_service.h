#pragma once

/// @file
/// Protocol runs on the bench for stored sessions (docs/PROTOCOLS.md, "Runs";
/// docs/ARCHITECTURE.md, "Runs"), transport-agnostic: HTTP and DDS call the
/// same methods.
///
/// RunService holds the commands and the live run. Start loads the session
/// and subject from storage and builds the protocols::SubjectContext
/// (threshold, max tolerated, range of motion, anthropometrics for Eq. 4.13,
/// the leg's approved parameter set for the model gate), stores the run
/// (state queued) with an audit entry in one transaction and hands it to the
/// BenchOwner (one run at a time). What the run produces is stored by the
/// RunRecorder (run_recorder.h); the runs of this process are in LiveRuns
/// (live_runs.h). A run's view turns final only once everything is stored.
///
/// Heartbeats: while a run is going, its controlling user must call
/// Heartbeat at least once per second (RunServiceConfig::heartbeat_timeout_s);
/// otherwise the heartbeat watchdog (server/safety/heartbeat_watchdog.h,
/// under everything a client reaches) stops the run (state aborted,
/// stimulation 0).
///
/// Errors are api::Status values; nothing a client sends can crash the
/// server. Exceptions from lower layers are caught here, logged and returned
/// as kInternal. Thread-safe.

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/status.h"
#include "server/bench/bench.h"
#include "server/protocols/bench_owner.h"
#include "server/protocols/protocol.h"
#include "server/protocols/runner.h"
#include "server/services/actor.h"
#include "server/services/live_runs.h"
#include "server/services/run_recorder.h"
#include "server/services/sample_hub.h"
#include "storage/database.h"
#include "storage/sessions.h"

namespace fesbench::server::services {

struct RunServiceConfig {
  /// Bench seconds per wall second the bench is paced at (0 = as fast as
  /// possible): only for the ETA.
  double time_scale = 1.0;
  /// The controlling user must heartbeat within this many wall seconds
  /// during a run (docs/SAFETY.md, "Heartbeat watchdog").
  double heartbeat_timeout_s = 1.0;
  bool arm_watchdog = true;                ///< false only in tests and offline replays.
  double progress_interval_s = 0.1;        ///< bench seconds between progress events.
  std::size_t batch_samples = 40;          ///< samples per live batch.
  std::size_t finished_runs_kept = 64;     ///< finished run views kept in memory.
  api::Clock* clock = api::Clock::Real();  ///< watchdog and run durations; outlives the service.
  /// Where unexpected errors are logged; empty = std::cerr.
  std::function<void(std::string_view)> log;
};

/// The live or stored view of a run (GET runs/{id}; api/run.h).
using RunView = api::RunView;

/// What the bench is doing (GET bench, DDS fesbench/bench/state; api/run.h).
using BenchState = api::BenchState;

/// A session with the context its runs are scaled to.
struct SessionContext {
  storage::Session session;
  protocols::SubjectContext subject;
  /// The leg's approved parameter set (model gate, tracking, daily check,
  /// rapid inertia; docs/SAFETY.md).
  std::optional<std::int64_t> parameter_set_id;
  bool has_stimulation_limits = false;  ///< the session records threshold and max tolerated.
};

/// Builds the context of `session_id`: threshold and max tolerated from the
/// session (absent: 0 and the bench's max, usable by tolerance_test only),
/// range of motion = the bench's mechanical range (storage keeps none),
/// body mass and leg length (shank length) from the subject's current
/// anthropometrics for Eq. 4.13 (§4.2.1), and the leg's approved parameter
/// set (or, with none, whether sets await approval). kNotFound for an
/// unknown session; kDataLoss for unreadable stored data.
api::Result<SessionContext> LoadSessionContext(storage::Database& db, std::int64_t session_id,
                                               const BenchLimits& limits);

/// The reason stored for a run that a stopped process left unfinished.
inline constexpr const char* kStoppedDuringRunReason = "server stopped during the run";

/// What RunService::RecoverAfterRestart found and did.
struct Recovery {
  std::vector<std::int64_t> failed_run_ids;  ///< runs closed as failed, oldest first.
  std::optional<std::string> estop_source;   ///< source of the re-latched e-stop, if any.
};

using protocols::TargetSamples;

class RunService {
 public:
  /// @param db, bench and hub must outlive the service.
  RunService(storage::Database& db, Bench& bench, SampleHub& hub, RunServiceConfig config = {});
  /// Shutdown().
  ~RunService();
  RunService(const RunService&) = delete;
  RunService& operator=(const RunService&) = delete;

  /// Starts `protocol` for the session. Errors: kPermissionDenied unless a
  /// clinician or admin; kNotFound for an unknown session or protocol;
  /// kInvalidArgument naming the parameter ("parameters.<name>"; the rapid
  /// protocol without an inertia source: "parameters.inertia_kgm2");
  /// kFailedPrecondition when the session has no threshold/max tolerated
  /// (any protocol but tolerance_test) or the model gate refuses; kConflict
  /// while another run holds the
  /// bench or an e-stop is latched; kUnavailable after Shutdown.
  /// `ceiling_reason`: a clinician's reason for a tolerance test whose
  /// ceiling_ma goes above the session's recorded max tolerated amplitude
  /// (up to the stimulator's limit); audited as "run.ceiling_above_max".
  /// `target`: tracking's uploaded trajectory (parameters.target =
  /// uploaded): resampled at 200 Hz; kInvalidArgument "target_samples" when
  /// it is malformed (model::ResampleTarget's words), longer than 600 s,
  /// leaves the range of motion, or comes without an uploaded target.
  api::Result<RunView> Start(const Actor& actor, std::int64_t session_id,
                             const std::string& protocol,
                             const protocols::ParameterValues& parameters,
                             const std::optional<std::string>& ceiling_reason = std::nullopt,
                             const TargetSamples* target = nullptr);

  /// The run's view: live (this process) or from storage. kNotFound.
  api::Result<RunView> Get(std::int64_t run_id);
  /// Blocks until the run's view is final (everything stored) or `timeout`
  /// passes, then returns the view. kNotFound for unknown ids.
  api::Result<RunView> Wait(std::int64_t run_id, std::chrono::milliseconds timeout);

  /// Cancels the current run (aborted, stimulation 0). kPermissionDenied
  /// unless clinician/admin; kNotFound for an unknown run; kConflict if the
  /// run is not the one in progress (already finished). Audited.
  api::Status Cancel(const Actor& actor, std::int64_t run_id);
  /// "Stop with result" (tolerance_test ends its ramp at the current
  /// amplitude; other protocols: cancel). Errors as Cancel. Audited.
  api::Status StopWithResult(const Actor& actor, std::int64_t run_id);
  /// Heartbeat of the controlling user (at least once per second during a
  /// run). kNotFound for an unknown run; kConflict if it is not in progress;
  /// kPermissionDenied for another user than the one who started it.
  api::Status Heartbeat(const Actor& actor, std::int64_t run_id);

  /// E-stop from any source ("http", "dds", "button", …) and any role: acts
  /// at once (BenchOwner::EStop, before anything else), latches, then is
  /// audited. A running protocol aborts within one control period.
  api::Status EStop(const Actor& actor, std::string_view source);
  /// Clears a latched e-stop. kPermissionDenied unless clinician/admin;
  /// kConflict while a run is still winding down. Audited.
  api::Status ClearEStop(const Actor& actor);

  /// This server no longer holds its bench (docs/SAFETY.md, "One server per
  /// bench"): acts as an e-stop from "bench lock lost" (stimulation stops at
  /// once, the latch is set and stored), then refuses to start runs and to
  /// clear the e-stop with kUnavailable naming `reason`, until RegainBench.
  void LoseBench(const std::string& reason);
  /// The bench is this server's again: runs may start once a person has
  /// cleared the e-stop LoseBench latched.
  void RegainBench();

  /// At start, before serving (no run of this process exists yet): closes
  /// every run that a stopped process left queued or running — state failed,
  /// reason kStoppedDuringRunReason, audited "run.recovered" by "system";
  /// the trials it stored stay readable — and latches the e-stop again if it
  /// was stored as latched (audited "bench.estop_restored"), until a person
  /// clears it. Errors: storage errors (the server must not serve then).
  api::Result<Recovery> RecoverAfterRestart();

  BenchState State() const;

  /// Runs `fn` while no run holds the bench and none can start (BenchService
  /// replaces the virtual subject this way); kConflict if a run is going.
  api::Status WithIdleBench(const std::function<api::Status()>& fn);

  /// Refuses new runs, cancels a run in progress (stimulation 0, state
  /// aborted "server shutting down"), waits for it and for its records to be
  /// stored, and stops the recorder thread. Idempotent; safe from a signal
  /// handler's helper thread (not from the signal handler itself).
  void Shutdown();

  const RunServiceConfig& config() const { return config_; }
  /// The bench, to read (its kind, its limits): every command goes through
  /// the bench owner's SafeBench (docs/SAFETY.md).
  const Bench& bench() const { return bench_; }
  protocols::BenchOwner& bench_owner() { return owner_; }

 private:
  std::shared_ptr<LiveRun> FindLive(std::int64_t run_id) const { return runs_.Find(run_id); }
  api::Result<RunView> StoredView(std::int64_t run_id);
  api::Status CheckCurrent(std::int64_t run_id, std::shared_ptr<LiveRun>* run);
  // StartImpl's parts.
  api::Status CheckBenchFree();
  api::Result<protocols::StartRequest> BuildStartRequest(
      const SessionContext& context, const std::string& protocol,
      const protocols::ParameterValues& parameters,
      const std::optional<std::string>& ceiling_reason, const TargetSamples* target);
  api::Result<storage::Run> CreateRunRecord(const Actor& actor, std::int64_t session_id,
                                            const std::string& protocol,
                                            const protocols::ParameterValues& parameters,
                                            const protocols::Plan& plan,
                                            const SessionContext& context,
                                            const std::optional<std::string>& ceiling_reason);
  std::shared_ptr<LiveRun> RegisterLiveRun(const Actor& actor, const storage::Run& created,
                                           const protocols::Plan& plan,
                                           const protocols::ProtocolDescription& description,
                                           const SessionContext& context, std::int64_t session_id,
                                           const std::string& protocol);
  api::Result<RunView> StartImpl(const Actor& actor, std::int64_t session_id,
                                 const std::string& protocol,
                                 const protocols::ParameterValues& parameters,
                                 const std::optional<std::string>& ceiling_reason,
                                 const TargetSamples* target);
  void Log(std::string_view message) const;
  /// Runs a command's body; an exception (never an expected failure) is
  /// logged under `command` and becomes kInternal(`failure`).
  template <class Fn>
  auto Guarded(std::string_view command, const char* failure, Fn&& fn) const -> decltype(fn());

  storage::Database& db_;
  Bench& bench_;
  SampleHub& hub_;
  RunServiceConfig config_;
  protocols::BenchOwner owner_;
  LiveRuns runs_;

  std::mutex start_mu_;  // serialises Start, WithIdleBench and Shutdown
  mutable std::mutex mu_;  // guards the three below
  std::string estop_source_;
  bool shutting_down_ = false;
  std::string bench_lost_;  // why this server lost its bench; empty while it holds it

  // Last: stopped first (its thread uses runs_ and owner_).
  RunRecorder recorder_;
};

}  // namespace fesbench::server::services
