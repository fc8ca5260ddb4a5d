#pragma once

/// @file
/// RunService's internals, shared by its two files: run_service.cc (the run
/// controller: start, heartbeat, cancel, stop, e-stop, views) and
/// run_recording.cc (the recorder: states, trials, the end of a run with its
/// parameter set and session limits). Not for other users.

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <iostream>
#include <map>
#include <set>
#include <sstream>
#include <utility>

#include "model/tracking.h"
#include "server/protocols/rapid_identification.h"
#include "server/protocols/run_outcome.h"
#include "storage/audit_log.h"
#include "storage/estop_latch.h"
#include "storage/parameter_sets.h"
#include "storage/subjects.h"
#include "server/services/run_service.h"
#include "storage/trials.h"

namespace fesbench::server::services {

using protocols::RunState;

inline std::string RunTarget(std::int64_t run_id) { return "runs/" + std::to_string(run_id); }

/// The reason of the session revision a tolerance_test run stores (for
/// people reading the session's history; the run's outcome names the
/// revision).
inline std::string ToleranceRevisionReason(std::int64_t run_id) {
  return "tolerance_test run " + std::to_string(run_id);
}

inline std::string FormatNumber(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// --- the live run ---------------------------------------------------------------------

struct RunService::LiveRun {
  // Fixed at start.
  std::int64_t run_id = 0;
  std::int64_t subject_id = 0;
  std::int64_t leg_id = 0;
  Actor actor;
  protocols::BenchMode mode = protocols::BenchMode::kLocked;
  std::optional<protocols::RapidSettings> rapid;
  std::optional<std::int64_t> prior_parameter_set_id;
  protocols::ProtocolKind kind = protocols::ProtocolKind::kIsometric;
  // Recorder thread only: the last state stored (the error transition starts there).
  RunState stored_state = RunState::kQueued;
  // Guarded by RunService::mu_.
  RunView view;
  std::vector<std::optional<std::int64_t>> trial_ids;  // by trial index
  bool final = false;
  /// Handed to the BenchOwner: its end waits for the bench to be released.
  std::atomic<bool> on_bench{false};
  // Run thread only.
  std::uint64_t next_sample = 0;
};

/// The runner's observer: runs on the run's thread, so it only updates the
/// in-memory view, copies into the hub and queues storage work.
class RunService::Observer final : public protocols::RunObserver {
 public:
  Observer(RunService& service, std::shared_ptr<LiveRun> run)
      : service_(service), run_(std::move(run)) {}

  void OnStateChanged(RunState state, const std::string& reason) override {
    Guard("state", [&] {
      if (state != RunState::kRunning) return;  // final states: after storing (RecordFinish)
      {
        std::lock_guard lock(service_.mu_);
        run_->view.state = state;
        run_->view.started_at = service_.db_.Now();
      }
      HubItem item;
      item.kind = HubItem::Kind::kState;
      item.run_id = run_->run_id;
      item.state = state;
      item.reason = reason;
      service_.hub_.Publish(std::move(item));
      service_.Enqueue(
          [&s = service_, run = run_, state, reason] { s.RecordState(run, state, reason); });
    });
  }

  void OnProgress(const protocols::Progress& progress) override {
    Guard("progress", [&] {
      {
        std::lock_guard lock(service_.mu_);
        run_->view.progress = progress;
      }
      HubItem item;
      item.kind = HubItem::Kind::kProgress;
      item.run_id = run_->run_id;
      item.progress = progress;
      service_.hub_.Publish(std::move(item));
    });
  }

  void OnSamples(const protocols::SampleBatch& batch) override {
    Guard("samples", [&] {
      HubItem item;
      item.kind = HubItem::Kind::kSamples;
      item.run_id = run_->run_id;
      item.first_sample = run_->next_sample;
      item.samples = batch;
      run_->next_sample += batch.t_s.size();
      service_.hub_.Publish(std::move(item));
    });
  }

  void OnTrial(const protocols::RecordedTrial& trial) override {
    Guard("trial", [&] {
      service_.Enqueue([&s = service_, run = run_, copy = trial] { s.RecordTrial(run, copy); });
    });
  }

  void OnFinished(const protocols::RunResult& result) override {
    Guard("finish", [&] {
      protocols::RunResult copy;  // everything but the trials (already queued)
      copy.state = result.state;
      copy.reason = result.reason;
      copy.protocol = result.protocol;
      copy.protocol_version = result.protocol_version;
      copy.parameters = result.parameters;
      copy.parameter_set = result.parameter_set;
      copy.tolerance = result.tolerance;
      copy.daily_check = result.daily_check;
      copy.safety_events = result.safety_events;
      copy.values = result.values;
      copy.bench_duration_s = result.bench_duration_s;
      copy.wall_duration_s = result.wall_duration_s;
      service_.Enqueue(
          [&s = service_, run = run_, r = std::move(copy)] { s.RecordFinish(run, r); });
    });
  }

 private:
  // An observer must never throw into the control loop.
  template <typename F>
  void Guard(const char* what, F&& f) noexcept {
    try {
      f();
    } catch (const std::exception& e) {
      service_.Log(std::string("run observer (") + what + "): " + e.what());
    } catch (...) {
      service_.Log(std::string("run observer (") + what + "): unknown exception");
    }
  }

  RunService& service_;
  std::shared_ptr<LiveRun> run_;
};

}  // namespace fesbench::server::services
