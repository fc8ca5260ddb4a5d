#include "server/protocols/run_outcome.h"

#include <sstream>
#include <utility>

#include "server/protocols/run_transitions.h"

namespace fesbench::server::protocols {
namespace {

std::string FormatNumber(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

std::optional<bool> FlagOf(const std::map<std::string, double>& values, const char* name) {
  const auto it = values.find(name);
  if (it == values.end()) return std::nullopt;
  return it->second == 1.0;
}

std::optional<double> FigureOf(const std::map<std::string, double>& values, const char* name) {
  const auto it = values.find(name);
  if (it == values.end()) return std::nullopt;
  return it->second;
}

// docs/SAFETY.md, tolerance test ceiling: the ramp reaching its ceiling
// says only that the subject bore the ceiling, not where their limit is.
// Only a limit the subject signalled or the clinician stopped at is a
// measured max tolerated amplitude.
api::ToleranceOutcome ConcludeTolerance(const RunResult& result, const ParameterValues& parameters,
                                        bool done) {
  api::ToleranceOutcome t;
  t.test = *result.tolerance;
  t.threshold_ma = result.tolerance->threshold_ma;
  t.subject_signalled_limit = FlagOf(result.values, "subject_signalled_limit");
  t.ended_at_ceiling = done && !result.tolerance->stopped_by_clinician &&
                       !t.subject_signalled_limit.value_or(false);
  if (t.ended_at_ceiling) {
    t.message = CeilingMessage(parameters);
    t.test->warnings.push_back(t.message);
  } else {
    t.max_tolerated_ma = result.tolerance->max_tolerated_ma;
    if (done && !t.threshold_ma) {
      t.test->warnings.push_back(
          "no threshold was detected: the session's threshold and max tolerated are unchanged");
    }
  }
  return t;
}

std::optional<api::AmplitudeSearchOutcome> ConcludeAmplitudeSearch(
    const std::map<std::string, double>& values) {
  api::AmplitudeSearchOutcome a;
  a.rb_amplitude_ma = FigureOf(values, "rb_amplitude_ma");
  a.full_extension_amplitude_ma = FigureOf(values, "full_extension_amplitude_ma");
  a.full_extension_reached = FlagOf(values, "full_extension_reached");
  if (!a.rb_amplitude_ma && !a.full_extension_amplitude_ma && !a.full_extension_reached) {
    return std::nullopt;
  }
  return a;
}

std::optional<std::int64_t> UsedSet(const RunConclusionInput& input) {
  switch (input.kind) {
    case ProtocolKind::kTracking:
      if (auto named = api::UsedParameterSetOf(input.parameters)) return named;
      return input.leg_parameter_set_id;
    case ProtocolKind::kDailyCheck:
    case ProtocolKind::kPrediction:
      return input.leg_parameter_set_id;
    default:
      return std::nullopt;
  }
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

api::RunOutcome ConcludeRun(const RunConclusionInput& input, const RunResult& result) {
  api::RunOutcome o;
  o.state = result.state;
  o.reason = result.reason;
  if (!IsFinal(result.state)) {
    o = FailOutcome(std::move(o), result.state,
                    "the run ended in state " + std::string(RunStateName(result.state)));
  }
  const bool done = o.state == RunState::kDone;
  o.used_parameter_set_id = UsedSet(input);
  if (result.tolerance) o.tolerance = ConcludeTolerance(result, input.parameters, done);
  o.amplitude_search = ConcludeAmplitudeSearch(result.values);
  if (result.daily_check) {
    api::Result<api::DailyCheckOutcome> report = api::DailyCheckOutcomeFromJson(*result.daily_check);
    if (report.ok()) o.daily_check = *std::move(report);
  }
  if (input.kind == ProtocolKind::kTracking) o.tracking = api::TrackingOutcome{result.values};
  return o;
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
