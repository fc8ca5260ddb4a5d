#pragma once

/// @file
/// A run's conclusion (docs/PROTOCOLS.md, "Runs"): what the runner produced
/// turned into the one outcome the run stores (api/run_outcome.h). Each
/// protocol's class concludes its own runs (Protocol::Conclude,
/// protocol_registry.h) from the part every run shares (ConcludeCommon). The
/// state moves only by the run transitions (run_transitions.h): a run whose
/// end could not be stored, or that the runner left unfinished, fails by the
/// error transition from the state it is stored in.

#include <cstdint>
#include <optional>
#include <string>

#include "api/run_outcome.h"
#include "server/protocols/protocol.h"
#include "server/protocols/runner.h"

namespace fesbench::server::protocols {

/// What ran, as ConcludeRun needs it.
struct RunConclusionInput {
  std::string protocol;        ///< its name: that protocol's class concludes.
  ParameterValues parameters;  ///< the plan's resolved values.
  /// The leg's approved set when the run started (the model gate's, the
  /// daily check's and tracking's by default; docs/SAFETY.md).
  std::optional<std::int64_t> leg_parameter_set_id;
};

/// The outcome of `result`: the Conclude of the protocol named by
/// input.protocol (ConcludeCommon for a name no protocol has). The set it
/// makes and the revision it writes are the recorder's to fill in once
/// stored.
api::RunOutcome ConcludeRun(const RunConclusionInput& input, const RunResult& result);

/// What every run's outcome has: its terminal state and reason; a state
/// that is not final fails by the error transition (FailOutcome).
api::RunOutcome ConcludeCommon(const RunResult& result);

/// The figure `name` the run decided (RunResult::values), or unset.
std::optional<double> RunFigure(const RunResult& result, const std::string& name);
/// The flag `name` the run decided (1 = true), or unset.
std::optional<bool> RunFlag(const RunResult& result, const std::string& name);

/// The outcome of a run stored in state `stored` (queued or running) that
/// fails for `reason` before its end is stored (refused at the start, or
/// its end could not be written): the error transition from `stored`; the
/// figures stay, the set and revision are dropped.
api::RunOutcome FailOutcome(api::RunOutcome outcome, RunState stored, std::string reason);

/// The message of a tolerance test that ended at its ceiling (docs/SAFETY.md,
/// tolerance test ceiling), naming the ceiling in `parameters`.
std::string CeilingMessage(const ParameterValues& parameters);

}  // namespace fesbench::server::protocols
