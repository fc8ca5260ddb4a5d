#pragma once

/// @file
/// The conclusion parts several of the catalogue's protocol classes share
/// (Protocol::Conclude; docs/PROTOCOLS.md, "Runs").

#include "api/run_outcome.h"
#include "server/protocols/run_outcome.h"

namespace fesbench::server::protocols::catalog {

/// ConcludeCommon, and as the set the run used the leg's approved set when
/// it started: the set the prediction protocols are gated by and the one
/// daily_check compares today's leg with (docs/SAFETY.md, model gate).
inline api::RunOutcome ConcludeWithLegSet(const RunConclusionInput& input,
                                          const RunResult& result) {
  api::RunOutcome o = ConcludeCommon(result);
  o.used_parameter_set_id = input.leg_parameter_set_id;
  return o;
}

}  // namespace fesbench::server::protocols::catalog
