#pragma once

/// @file
/// What a run says about itself on the wire (docs/PROTOCOLS.md, "Runs";
/// docs/API.md: `runs`, `bench`, `runs/{id}/stream`): its progress, the safety
/// events of the bench, live sample batches, the tolerance test's outcome,
/// the run resource, the bench state and the events of a run's stream. One
/// definition for the server that writes them (HTTP, SSE, DDS) and the
/// clients that read them (CLI, study). Keys carry units; numbers that are
/// not finite travel as null.
///
/// The readers (…FromJson) check the types of the fields they know and
/// ignore fields they do not, so a client keeps working against a newer
/// server; a missing or mistyped field they need is kInvalidArgument naming
/// it.

#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "api/clock.h"
#include "api/run_outcome.h"
#include "api/run_state.h"
#include "api/status.h"

namespace fesbench::api {

/// A protocol's parameter values by name (units in the names).
using ParameterValues = std::map<std::string, double, std::less<>>;

/// What a protocol step is doing.
enum class StepPhase { kPrepare, kOffset, kStimulate, kRest, kMove, kIdentify };
/// "prepare", "offset", "stimulate", "rest", "move", "identify".
std::string_view StepPhaseName(StepPhase phase);
std::optional<StepPhase> ParseStepPhase(std::string_view name);

/// Progress of a run: bench-time fraction and an ETA in wall seconds.
struct Progress {
  double fraction = 0.0;  ///< 0–1 of the plan's bench time.
  double eta_s = 0.0;     ///< wall seconds left (bench s / time scale, or measured).
  double bench_elapsed_s = 0.0;  ///< bench time run so far.
  /// The run's bench time: while it runs, the plan's less what steps that
  /// ended early skipped; once it ended (done, failed, aborted), the time
  /// it ran (docs/API.md, Runs).
  double bench_total_s = 0.0;
  double bench_planned_s = std::numeric_limits<double>::quiet_NaN();  ///< the plan's; NaN: unknown.
  std::size_t step = 0;
  StepPhase phase = StepPhase::kPrepare;
};
/// {"fraction", "eta_s" (null when unknown), "bench_elapsed_s",
///  "bench_total_s", "bench_planned_s" (null when unknown), "step", "phase"}.
nlohmann::json ProgressToJson(const Progress& progress);
/// An unknown ETA (null) reads as NaN.
Result<Progress> ProgressFromJson(const nlohmann::json& json);

/// Something the safety layer did (server/safety/safe_bench.h).
struct SafetyEvent {
  enum class Kind { kStimClamped, kSetpointClamped, kEStop, kEStopCleared, kWatchdog };
  Kind kind = Kind::kEStop;
  double t_s = 0.0;        ///< bench time.
  double requested = 0.0;  ///< what was asked (mA or deg), NaN if not applicable.
  double applied = 0.0;    ///< what the bench got.
  std::string detail;
};
/// "stim_clamped", "setpoint_clamped", "estop", "estop_cleared", "watchdog".
std::string_view SafetyEventKindName(SafetyEvent::Kind kind);
std::optional<SafetyEvent::Kind> ParseSafetyEventKind(std::string_view name);
/// {"kind", "t_s", "requested", "applied", "detail"}.
nlohmann::json SafetyEventToJson(const SafetyEvent& event);
Result<SafetyEvent> SafetyEventFromJson(const nlohmann::json& json);

/// A batch of live samples of one trial.
struct SampleBatch {
  int trial = -1;  ///< index of the trial within the run.
  std::string trial_name;
  std::vector<double> t_s, stim_ma, angle_deg, torque_nm, accel_m_s2;
  /// Tracking runs (docs/PROTOCOLS.md, `tracking`): the target and the controller's τ̂_scale.
  std::vector<double> target_deg, tau_scale_nm;
};
/// {"trial", "trial_name", "t_s", "stim_ma", "angle_deg", "torque_nm",
///  "accel_m_s2"} plus "target_deg", "tau_scale_nm" when present.
nlohmann::json SampleBatchToJson(const SampleBatch& batch);
Result<SampleBatch> SampleBatchFromJson(const nlohmann::json& json);

/// The run resource (GET /runs/{id}, the runs lists, run commands' replies).
struct RunView {
  std::int64_t run_id = 0;
  std::int64_t session_id = 0;
  std::string protocol;
  int protocol_version = 1;
  ParameterValues parameters;  ///< resolved values (defaults filled in).
  RunState state = RunState::kQueued;
  std::string reason;  ///< why failed or aborted; empty otherwise.
  std::string owner;   ///< user name of the actor who started it ("controller").
  std::optional<std::int64_t> owner_user_id;
  UtcTime created_at;
  std::optional<UtcTime> started_at;
  std::optional<UtcTime> finished_at;
  Progress progress;                             ///< fraction 0–1 and ETA (wall s).
  std::vector<std::int64_t> trial_ids;           ///< stored trials, in recording order.
  std::optional<std::int64_t> parameter_set_id;  ///< rapid_parameterisation's stored set.
  /// The set the run used (tracking: the set it inverts, "0: the approved
  /// set" resolved to its id when the run was started), or none.
  std::optional<std::int64_t> used_parameter_set_id;
  std::vector<SafetyEvent> safety_events;        ///< of this run (live/in-memory views only).
  /// What the run concluded (api/run_outcome.h), once it ended and was
  /// stored; the four fields below show it (ShowOutcome).
  std::optional<RunOutcome> outcome;
  std::optional<ToleranceResult> tolerance;      ///< tolerance_test: what it measured.
  std::map<std::string, double> values;          ///< RunValuesOf(outcome).
  /// What the run produced, for clients (null while running or when it
  /// produced nothing): RunResultJsonOf(outcome).
  nlohmann::json result;
  bool live = false;  ///< from memory (this process ran it) rather than storage.
};
/// {"run_id", "session_id", "protocol", "protocol_version" (int),
///  "parameters", "state" (queued|running|done|failed|aborted), "reason",
///  "progress" (0–1), "eta_s" (wall s, null when unknown), "created_at_utc",
///  "started_at_utc", "finished_at_utc" (ISO-8601 UTC or null), "result",
///  "controller" (user name or null)}, plus the details "bench_elapsed_s",
///  "bench_total_s" (the time run once it ended), "bench_planned_s",
///  "trial_ids", "parameter_set_id", "used_parameter_set_id", "values",
///  "safety_events", "live", "outcome" (RunOutcomeToJson, null until the
///  run ended) and, for tolerance_test runs, "tolerance".
nlohmann::json RunViewToJson(const RunView& view);
/// The fields above except "owner_user_id" (not sent); "tolerance" comes
/// from "outcome".
Result<RunView> RunViewFromJson(const nlohmann::json& json);
/// Sets view.outcome and what shows it: state, reason, parameter_set_id,
/// used_parameter_set_id (when the outcome names one), tolerance (what the
/// test measured), values (RunValuesOf) and result (RunResultJsonOf).
void ShowOutcome(const RunOutcome& outcome, RunView& view);
/// The set a run's resolved parameters name as the one it uses
/// (`parameter_set_id` ≥ 1: tracking's, docs/PROTOCOLS.md), or none.
std::optional<std::int64_t> UsedParameterSetOf(const ParameterValues& parameters);

/// What the bench is doing (GET /bench, DDS fesbench/bench/state).
struct BenchState {
  std::string kind;           ///< "sim", "replay", …
  std::string mode = "idle";  ///< the current run's bench mode, or "idle".
  bool busy = false;
  bool estopped = false;
  std::string estop_source;  ///< who latched it (last e-stop through the server).
  std::string owner;         ///< controlling user name, empty when idle.
  std::optional<std::int64_t> owner_user_id;
  std::optional<std::int64_t> run_id;  ///< the current run, or the last one.
  std::string protocol;
  RunState run_state = RunState::kQueued;
  Progress progress;
};
/// {"kind", "mode", "busy", "estopped", "estop_source", "owner",
///  "owner_user_id", "run_id", "protocol", "run_state", "progress"}.
nlohmann::json BenchStateToJson(const BenchState& state);
Result<BenchState> BenchStateFromJson(const nlohmann::json& json);

/// One event of a run's stream (SSE GET /runs/{id}/stream, GET /events).
struct RunEvent {
  enum class Kind {
    kState,     ///< state (and reason) of the run; also the first event of a subscription.
    kProgress,  ///< progress fraction 0–1 and ETA.
    kSamples,   ///< a batch of samples.
    kTrial,     ///< a trial was stored (trial index, name, stored id).
    kEnd,       ///< the run ended and everything it produced is stored.
    /// A parameter set was stored (by a run, an identification job or an
    /// import; run_id 0): parameter_set_id, subject_id, leg_id.
    kParameterSet,
  };
  Kind kind = Kind::kState;
  std::uint64_t seq = 0;    ///< server-wide, strictly increasing in publish order (from 1).
  std::int64_t run_id = 0;  ///< 0 when no run has started yet (initial state).
  RunState state = RunState::kQueued;  ///< kState, kEnd.
  std::string reason;                  ///< kState, kEnd.
  Progress progress;                   ///< kState, kProgress.
  SampleBatch samples;                 ///< kSamples; kTrial: trial and trial_name.
  /// kSamples: index within the run of the batch's first sample (0, 40, 80,
  /// … over all trials of the run): consecutive batches continue it without
  /// gaps, so a subscriber can check it received every sample in order.
  std::uint64_t first_sample = 0;
  std::optional<std::int64_t> trial_id;          ///< kTrial: the stored trial.
  std::optional<std::int64_t> parameter_set_id;  ///< kEnd, kParameterSet: a stored set.
  std::int64_t subject_id = 0;                   ///< kParameterSet.
  std::int64_t leg_id = 0;                       ///< kParameterSet.
  /// kParameterSet: the set was approved (its leg's approved set now), not
  /// stored; such items feed the DDS topic, not the SSE stream of stored sets.
  bool approval = false;
  nlohmann::json result;  ///< kEnd: what the run produced (RunView::result), or null.
};
/// "state", "progress", "samples", "trial", "end", "parameter_set" (the SSE
/// event name).
std::string_view RunEventKindName(RunEvent::Kind kind);
std::optional<RunEvent::Kind> ParseRunEventKind(std::string_view name);
/// {"seq", "run_id", "kind", …} plus, by kind, "state"/"reason"/"progress",
/// "progress", "samples" with "first_sample", "trial"/"trial_name"/
/// "trial_id", "state"/"reason"/"parameter_set_id"/"result", or
/// "parameter_set_id"/"subject_id"/"leg_id".
nlohmann::json RunEventToJson(const RunEvent& event);
Result<RunEvent> RunEventFromJson(const nlohmann::json& json);

}  // namespace fesbench::api
