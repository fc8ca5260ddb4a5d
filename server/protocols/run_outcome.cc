#include "server/protocols/run_outcome.h"

#include <sstream>
#include <utility>

#include "server/protocols/protocol_registry.h"
#include "server/protocols/run_transitions.h"

namespace fesbench::server::protocols {
namespace {

std::string FormatNumber(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

std::string CeilingMessage(const ParameterValues& parameters) {
  const auto ceiling = parameters.find("ceiling_ma");
  const std::string at = ceiling == parameters.end()
                             ? std::string("its ceiling")
                             : "its ceiling of " + FormatNumber(ceiling->second) + " mA";
  return "the ramp reached " + at +
         " without the subject signalling the limit or a clinician stopping it: no max "
         "tolerated amplitude was measured, and the session's threshold and max tolerated are "
         "unchanged; re-test (stop the ramp where the subject says so), or enter the max "
         "tolerated amplitude as a clinician (a correction of the session)";
}

std::optional<double> RunFigure(const RunResult& result, const std::string& name) {
  const auto it = result.values.find(name);
  if (it == result.values.end()) return std::nullopt;
  return it->second;
}

std::optional<bool> RunFlag(const RunResult& result, const std::string& name) {
  const std::optional<double> v = RunFigure(result, name);
  if (!v) return std::nullopt;
  return *v == 1.0;
}

api::RunOutcome ConcludeCommon(const RunResult& result) {
  api::RunOutcome o;
  o.state = result.state;
  o.reason = result.reason;
  if (!IsFinal(result.state)) {
    o = FailOutcome(std::move(o), result.state,
                    "the run ended in state " + std::string(RunStateName(result.state)));
  }
  return o;
}

api::RunOutcome Protocol::Conclude(const RunConclusionInput& /*input*/,
                                   const RunResult& result) const {
  return ConcludeCommon(result);
}

api::RunOutcome ConcludeRun(const RunConclusionInput& input, const RunResult& result) {
  const RegisteredProtocol* registered = FindRegisteredProtocol(input.protocol);
  if (registered == nullptr) return ConcludeCommon(result);
  return registered->protocol->Conclude(input, result);
}

api::RunOutcome FailOutcome(api::RunOutcome outcome, RunState stored, std::string reason) {
  if (const std::optional<RunState> failed = NextState(stored, RunTransition::kError)) {
    outcome.state = *failed;
    outcome.reason = std::move(reason);
    outcome.parameter_set_id.reset();
    outcome.session_revision.reset();
  }
  return outcome;
}

}  // namespace fesbench::server::protocols
