#pragma once

/// @file
/// The run life cycle (docs/PROTOCOLS.md, "Runs"; an explicit state machine
/// with an error state and named transitions, as rclcpp_lifecycle):
///
///   queued ──start──▶ running ──complete──▶ done
///                       │ ├──cancel / estop / watchdog──▶ aborted
///                       │ └──error──▶ failed      (the error state)
///   queued ──cancel──▶ aborted,  queued ──error──▶ failed (refused)
///
/// done, failed and aborted are final: every other transition is refused.

#include <optional>
#include <string_view>

#include "api/run_state.h"

namespace fesbench::server::protocols {

using api::IsFinal;
using api::RunState;
using api::RunStateName;
enum class RunTransition { kStart, kComplete, kCancel, kEStop, kWatchdog, kError };

/// "start", "complete", "cancel", "estop", "watchdog", "error".
std::string_view RunTransitionName(RunTransition transition);
/// The state `transition` leads to from `state`, or nullopt if the
/// transition is not allowed there.
std::optional<RunState> NextState(RunState state, RunTransition transition);

}  // namespace fesbench::server::protocols
