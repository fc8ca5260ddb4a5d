#include "api/run_state.h"

namespace fesbench::api {

std::string_view RunStateName(RunState state) {
  switch (state) {
    case RunState::kQueued:
      return "queued";
    case RunState::kRunning:
      return "running";
    case RunState::kDone:
      return "done";
    case RunState::kFailed:
      return "failed";
    case RunState::kAborted:
      return "aborted";
  }
  return "failed";
}

std::optional<RunState> ParseRunState(std::string_view name) {
  for (RunState state : {RunState::kQueued, RunState::kRunning, RunState::kDone, RunState::kFailed,
                         RunState::kAborted}) {
    if (RunStateName(state) == name) return state;
  }
  return std::nullopt;
}

bool IsFinal(RunState state) {
  return state == RunState::kDone || state == RunState::kFailed || state == RunState::kAborted;
}

}  // namespace fesbench::api
