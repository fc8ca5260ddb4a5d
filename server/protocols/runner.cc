#include "server/protocols/runner.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>

#include "api/model_call.h"
#include "model/identify_isometric.h"
#include "model/simulate.h"
#include "server/protocols/run_execution.h"

namespace fesbench::server::protocols {
namespace {

}  // namespace

void ApplySearchedAmplitude(const Plan& plan, std::optional<double> reached_ma,
                            std::map<std::string, double>& values, std::vector<double>& stim_scale,
                            std::vector<double>& stim_floor) {
  if (!plan.adaptive_amplitude) return;
  const AdaptiveAmplitude& adapt = *plan.adaptive_amplitude;
  if (!(adapt.planned_ma > adapt.min_ma)) return;
  // §5.4.3: the amplitude that just reaches full extension; the max
  // tolerated (the search's end) when the knee never got there.
  const double chosen = std::clamp(reached_ma.value_or(adapt.max_ma), adapt.min_ma, adapt.max_ma);
  values["full_extension_amplitude_ma"] = chosen;
  values["full_extension_reached"] = reached_ma ? 1.0 : 0.0;
  const double top = std::max(chosen, adapt.min_ma + std::clamp(adapt.min_top_fraction, 0.0, 1.0) *
                                                         (adapt.max_ma - adapt.min_ma));
  values["rb_amplitude_ma"] = top;
  for (int t : adapt.trials) {
    if (t < 0 || static_cast<std::size_t>(t) >= stim_scale.size()) continue;
    // Levels above threshold keep their place between threshold and the
    // top level: u → min + (u − min)·(top − min)/(planned − min).
    stim_floor[static_cast<std::size_t>(t)] = adapt.min_ma;
    stim_scale[static_cast<std::size_t>(t)] =
        (top - adapt.min_ma) / (adapt.planned_ma - adapt.min_ma);
  }
}

// --- SafetyEventLog -----------------------------------------------------------

SafeBench::EventSink SafetyEventLog::sink() {
  return [this](const SafetyEvent& e) { Append(e); };
}

void SafetyEventLog::Append(const SafetyEvent& event) {
  std::lock_guard lock(mu_);
  events_.push_back(event);
}

std::size_t SafetyEventLog::size() const {
  std::lock_guard lock(mu_);
  return events_.size();
}

std::vector<SafetyEvent> SafetyEventLog::Since(std::size_t from) const {
  std::lock_guard lock(mu_);
  if (from >= events_.size()) return {};
  return {events_.begin() + static_cast<std::ptrdiff_t>(from), events_.end()};
}

// --- ProtocolRunner -------------------------------------------------------------

ProtocolRunner::ProtocolRunner(SafeBench& bench, SafetyEventLog* log, RunObserver* observer,
                               RunnerOptions options)
    : bench_(bench), log_(log), observer_(observer), options_(std::move(options)) {
  if (options_.clock == nullptr) options_.clock = api::Clock::Real();
}

void ProtocolRunner::Cancel(const std::string& reason) {
  {
    std::lock_guard lock(reason_mu_);
    if (cancel_reason_.empty()) cancel_reason_ = reason;
  }
  cancel_.store(true);
}

void ProtocolRunner::Stop() { stop_.store(true); }

bool ProtocolRunner::Transition(RunTransition transition, const std::string& reason) {
  const std::optional<RunState> next = NextState(state_.load(), transition);
  if (!next) return false;
  state_.store(*next);
  if (result_ != nullptr) {
    result_->state = *next;
    if (IsFinal(*next) && *next != RunState::kDone) result_->reason = reason;
  }
  if (observer_ != nullptr) observer_->OnStateChanged(*next, reason);
  return true;
}

RunResult ProtocolRunner::Run(const Plan& plan, const SubjectContext& subject) {
  if (state_.load() != RunState::kQueued) {
    RunResult used;
    used.state = RunState::kFailed;
    used.reason = "a ProtocolRunner runs one plan; this one has run already";
    used.protocol = plan.protocol;
    return used;
  }
  return RunExecution(*this, plan, subject).Execute();
}

api::Result<double> AmplitudeForTorque(const api::Trial& ramp_trial, double target_torque_nm,
                                       double min_ma, double max_ma) {
  const api::Result<model::IrcResult> irc = api::CallModel([&] {
    return model::IdentifyIrc(model::IrcMethod::kRampCorrelation, api::ToTrialColumns(ramp_trial));
  });
  if (!irc.ok()) {
    return api::Status::FailedPrecondition("IRC of the ramp trial: " + irc.status().message());
  }
  for (double u = min_ma; u <= max_ma; u += 0.1) {
    if (irc->torque_scale_nm * irc->irc(u) >= target_torque_nm) return u;
  }
  return max_ma;
}

}  // namespace fesbench::server::protocols
