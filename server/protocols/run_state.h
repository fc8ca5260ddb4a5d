#pragma once

/// @file
/// The run life cycle (DESIGN.md §5; STYLE.md: explicit state machines with
/// an error state and named transitions, as rclcpp_lifecycle):
///
///   queued ──start──▶ running ──complete──▶ done
///                       │ ├──cancel / estop / watchdog──▶ aborted
///                       │ └──error──▶ failed      (the error state)
///   queued ──cancel──▶ aborted,  queued ──error──▶ failed (refused)
///
/// done, failed and aborted are final: every other transition is refused.

#include <optional>
#include <string_view>

namespace fesbench::server::protocols {

enum class RunState { kQueued, kRunning, kDone, kFailed, kAborted };
enum class RunTransition { kStart, kComplete, kCancel, kEStop, kWatchdog, kError };

/// "queued", "running", "done", "failed", "aborted".
std::string_view RunStateName(RunState state);
/// "start", "complete", "cancel", "estop", "watchdog", "error".
std::string_view RunTransitionName(RunTransition transition);
/// True for done, failed and aborted.
bool IsFinal(RunState state);
/// The state `transition` leads to from `state`, or nullopt if the
/// transition is not allowed there.
std::optional<RunState> NextState(RunState state, RunTransition transition);

}  // namespace fesbench::server::protocols
