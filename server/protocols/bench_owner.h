#pragma once

/// @file
/// The one object that holds the bench (docs/SAFETY.md, "Admission of a
/// run": one controller holds the bench at a time): wraps the Bench in the SafeBench interlocks,
/// validates and plans start requests, applies model-gated stimulation, and
/// runs one protocol at a time on its own thread. A second Start while a
/// run holds the bench is refused with kConflict. Thread-safe.

#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "api/status.h"
#include "server/protocols/plan.h"
#include "server/protocols/runner.h"
#include "server/safety/safe_bench.h"

namespace fesbench::server::protocols {

/// A client's request to run a protocol.
struct StartRequest {
  std::string protocol;
  ParameterValues parameters;  ///< client values; the rest take defaults.
  SubjectContext subject;
  std::string client = "client";  ///< the controlling client (heart-beats).
  /// tracking with target = uploaded: the trajectory at 200 Hz, deg.
  std::vector<double> target_angle_deg = {};
};

struct BenchOwnerOptions {
  RunnerOptions runner;  ///< time_scale, watchdog, batching.
  /// The heartbeat watchdog's and the runs' clock (it replaces runner.clock);
  /// must outlive the owner.
  api::Clock* clock = api::Clock::Real();
};

class BenchOwner {
 public:
  /// @param bench must outlive the owner.
  explicit BenchOwner(Bench& bench, BenchOwnerOptions options = {});
  /// Cancels a run in progress and waits for it.
  ~BenchOwner();
  BenchOwner(const BenchOwner&) = delete;
  BenchOwner& operator=(const BenchOwner&) = delete;

  /// Resolves, validates and plans a request and applies the model gate,
  /// without touching the bench. kNotFound (unknown protocol),
  /// kInvalidArgument (bad parameter or subject; field named),
  /// kFailedPrecondition (model-gated stimulation refused).
  api::Result<Plan> Prepare(const StartRequest& request) const;

  /// Starts a run on a new thread. kConflict while another run holds the
  /// bench or while an e-stop is latched; otherwise as Prepare.
  /// `observer` receives the run's events on the run's thread.
  api::Status Start(const StartRequest& request, std::shared_ptr<RunObserver> observer = nullptr);

  /// Cancels the current run (kNotFound if none).
  api::Status Cancel(const std::string& reason = "cancelled by client");
  /// Stop with result (tolerance_test): kNotFound if no run.
  api::Status Stop();
  /// Blocks until the current (or last) run has finished and returns its
  /// result once; nullopt if there was none to return.
  std::optional<RunResult> Wait();
  bool busy() const;
  /// The controlling client of the current run, empty if none.
  std::string owner() const;

  /// Heartbeat of the controlling client (docs/SAFETY.md, "Heartbeat watchdog").
  void Heartbeat() { safe_.Heartbeat(); }
  /// E-stop from any source (HTTP, DDS, the bench button): at once, from
  /// any thread; latches until ClearEStop.
  void EStop(const std::string& source) { safe_.EStop(source); }
  /// kConflict while a run is still winding down.
  api::Status ClearEStop(const std::string& source);

  SafeBench& safe_bench() { return safe_; }
  const SafetyEventLog& events() const { return log_; }

 private:
  void JoinFinished();

  BenchOwnerOptions options_;
  SafetyEventLog log_;
  SafeBench safe_;
  mutable std::mutex mu_;
  std::mutex join_mu_;  // serialises joining the run thread
  std::condition_variable cv_;
  bool busy_ = false;
  std::string owner_;
  std::unique_ptr<ProtocolRunner> runner_;
  std::shared_ptr<RunObserver> observer_;
  std::thread thread_;
  std::optional<RunResult> last_;
};

}  // namespace fesbench::server::protocols
