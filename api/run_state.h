#pragma once

/// @file
/// The one run vocabulary (docs/PROTOCOLS.md, "Runs"): the states a run
/// passes through, used by storage, protocols, services, HTTP, SSE, DDS and
/// the clients alike.
///
///   queued ──▶ running ──▶ done | failed | aborted;  queued ──▶ failed | aborted
///
/// done, failed and aborted are final.

#include <optional>
#include <string_view>

namespace fesbench::api {

enum class RunState { kQueued, kRunning, kDone, kFailed, kAborted };

/// "queued", "running", "done", "failed", "aborted".
std::string_view RunStateName(RunState state);
/// The state named `name` (exactly the names above), or nullopt.
std::optional<RunState> ParseRunState(std::string_view name);
/// True for done, failed and aborted.
bool IsFinal(RunState state);

}  // namespace fesbench::api
