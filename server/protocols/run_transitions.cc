#include "server/protocols/run_transitions.h"

namespace fesbench::server::protocols {

std::string_view RunTransitionName(RunTransition transition) {
  switch (transition) {
    case RunTransition::kStart:
      return "start";
    case RunTransition::kComplete:
      return "complete";
    case RunTransition::kCancel:
      return "cancel";
    case RunTransition::kEStop:
      return "estop";
    case RunTransition::kWatchdog:
      return "watchdog";
    case RunTransition::kError:
      return "error";
  }
  return "error";
}

std::optional<RunState> NextState(RunState state, RunTransition transition) {
  switch (state) {
    case RunState::kQueued:
      if (transition == RunTransition::kStart) return RunState::kRunning;
      if (transition == RunTransition::kCancel) return RunState::kAborted;
      if (transition == RunTransition::kError) return RunState::kFailed;
      return std::nullopt;
    case RunState::kRunning:
      switch (transition) {
        case RunTransition::kComplete:
          return RunState::kDone;
        case RunTransition::kCancel:
        case RunTransition::kEStop:
        case RunTransition::kWatchdog:
          return RunState::kAborted;
        case RunTransition::kError:
          return RunState::kFailed;
        case RunTransition::kStart:
          return std::nullopt;
      }
      return std::nullopt;
    case RunState::kDone:
    case RunState::kFailed:
    case RunState::kAborted:
      return std::nullopt;
  }
  return std::nullopt;
}

}  // namespace fesbench::server::protocols
