#include "api/run_state.h"

#include "api/name_table.h"

namespace fesbench::api {

namespace {

constexpr NameTable<RunState, 5> kRunStates({{{RunState::kQueued, "queued"},
                                              {RunState::kRunning, "running"},
                                              {RunState::kDone, "done"},
                                              {RunState::kFailed, "failed"},
                                              {RunState::kAborted, "aborted"}}},
                                            "failed");

}  // namespace

std::string_view RunStateName(RunState state) { return kRunStates.Name(state); }

std::optional<RunState> ParseRunState(std::string_view name) { return kRunStates.Parse(name); }

bool IsFinal(RunState state) {
  return state == RunState::kDone || state == RunState::kFailed || state == RunState::kAborted;
}

}  // namespace fesbench::api
