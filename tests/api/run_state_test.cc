// The one run vocabulary (api/run_state.h; docs/PROTOCOLS.md, "Runs").

#include "api/run_state.h"

#include <gtest/gtest.h>

namespace fesbench::api {
namespace {

TEST(RunState, NamesParseBackAndOnlyTheEndStatesAreFinal) {
  const RunState all[] = {RunState::kQueued, RunState::kRunning, RunState::kDone,
                          RunState::kFailed, RunState::kAborted};
  const char* const names[] = {"queued", "running", "done", "failed", "aborted"};
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(RunStateName(all[i]), names[i]);
    EXPECT_EQ(ParseRunState(names[i]), all[i]);
  }
  EXPECT_FALSE(IsFinal(RunState::kQueued));
  EXPECT_FALSE(IsFinal(RunState::kRunning));
  EXPECT_TRUE(IsFinal(RunState::kDone));
  EXPECT_TRUE(IsFinal(RunState::kFailed));
  EXPECT_TRUE(IsFinal(RunState::kAborted));
  // The old storage words are not states any more.
  EXPECT_FALSE(ParseRunState("completed").has_value());
  EXPECT_FALSE(ParseRunState("cancelled").has_value());
  EXPECT_FALSE(ParseRunState("Done").has_value());
}

}  // namespace
}  // namespace fesbench::api
