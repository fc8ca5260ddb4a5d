#include "server/services/run_service.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <iostream>
#include <sstream>
#include <utility>

#include "api/model_call.h"
#include "model/tracking.h"
#include "server/protocols/run_outcome.h"
#include "storage/estop_latch.h"
#include "storage/parameter_sets.h"
#include "storage/subjects.h"
#include "storage/trials.h"

namespace fesbench::server::services {

using protocols::RunState;

// --- construction ------------------------------------------------

namespace {

protocols::BenchOwnerOptions OwnerOptions(const RunServiceConfig& c) {
  protocols::BenchOwnerOptions o;
  o.runner.time_scale = c.time_scale;
  o.runner.progress_interval_s = c.progress_interval_s;
  o.runner.batch_samples = std::max<std::size_t>(1, c.batch_samples);
  o.runner.arm_watchdog = c.arm_watchdog;
  o.runner.heartbeat_timeout_s = c.heartbeat_timeout_s;
  o.clock = c.clock;
  return o;
}

}  // namespace

RunService::RunService(storage::Database& db, Bench& bench, SampleHub& hub, RunServiceConfig config)
    : db_(db),
      bench_(bench),
      hub_(hub),
      config_(std::move(config)),
      owner_(bench, OwnerOptions(config_)),
      runs_(config_.finished_runs_kept),
      recorder_(db, hub, runs_, owner_, [this](std::string_view message) { Log(message); }) {}

RunService::~RunService() { Shutdown(); }

void RunService::Log(std::string_view message) const {
  if (config_.log) {
    config_.log(message);
  } else {
    std::cerr << "fesbench-server: run service: " << message << std::endl;
  }
}

// --- queries ------------------------------------------------------------------------

// A stored run reads back as it was stored: the runs table with its
// outcome (storage::RunViewOf) and its trials.
api::Result<RunView> RunService::StoredView(std::int64_t run_id) {
  api::Result<storage::Run> run = storage::SessionRepository(db_).GetRun(run_id);
  if (!run.ok()) return run.status();
  RunView v = storage::RunViewOf(*run);
  api::Result<std::vector<std::int64_t>> trial_ids = storage::TrialRepository(db_).IdsOfRun(run_id);
  if (!trial_ids.ok()) return trial_ids.status();
  v.trial_ids = std::move(*trial_ids);
  return v;
}

// The last guard around each command. Every expected failure comes back from
// the body as a Status; an exception here is resource exhaustion or a broken
// invariant (bad_alloc, system_error): logged, and answered with kInternal
// saying what could not be done.
template <class Fn>
auto RunService::Guarded(std::string_view command, const char* failure, Fn&& fn) const
    -> decltype(fn()) {
  try {
    return fn();
  } catch (const std::exception& e) {
    Log(std::string(command) + ": " + e.what());
    return api::Status::Internal(failure);
  }
}

api::Result<RunView> RunService::Get(std::int64_t run_id) {
  return Guarded("Get", "reading the run failed", [&]() -> api::Result<RunView> {
    if (auto run = FindLive(run_id)) return runs_.Locked([&] { return run->view; });
    return StoredView(run_id);
  });
}

api::Result<RunView> RunService::Wait(std::int64_t run_id, std::chrono::milliseconds timeout) {
  return Guarded("Wait", "reading the run failed", [&]() -> api::Result<RunView> {
    if (auto run = FindLive(run_id)) return runs_.WaitFinal(*run, timeout);
    return StoredView(run_id);
  });
}

BenchState RunService::State() const {
  BenchState s;
  s.kind = std::string(bench_.kind());
  s.estopped = const_cast<protocols::BenchOwner&>(owner_).safe_bench().estopped() ||
               bench_.HardwareEStopped();
  s.busy = owner_.busy();
  {
    std::lock_guard lock(mu_);
    if (s.estopped) s.estop_source = estop_source_;
  }
  // A device that failed latched the e-stop itself: it is the source.
  if (s.estopped && s.estop_source.empty()) {
    if (const api::Status fault = bench_.HardwareFault(); !fault.ok()) {
      s.estop_source = fault.message();
    }
  }
  const std::shared_ptr<LiveRun> run = runs_.Current();
  if (!run) return s;
  runs_.Locked([&] {
    s.run_id = run->run_id;
    s.protocol = run->view.protocol;
    s.run_state = run->view.state;
    s.progress = run->view.progress;
    if (!run->final) {
      s.busy = true;  // still storing what it produced
      s.mode = std::string(protocols::BenchModeName(run->mode));
      s.owner = run->actor.user_name;
      s.owner_user_id = run->actor.user_id;
    }
  });
  return s;
}

// --- commands ----------------------------------------------------------------------

api::Result<RunView> RunService::Start(const Actor& actor, std::int64_t session_id,
                                       const std::string& protocol,
                                       const protocols::ParameterValues& parameters,
                                       const std::optional<std::string>& ceiling_reason,
                                       const TargetSamples* target) {
  return Guarded("Start", "starting the run failed", [&]() -> api::Result<RunView> {
    return StartImpl(actor, session_id, protocol, parameters, ceiling_reason, target);
  });
}

namespace {

// Who may start which protocol with which values: the checks that need no
// session and no bench.
api::Result<const protocols::ProtocolDescription*> CheckStartRequest(
    const Actor& actor, const std::string& protocol, const protocols::ParameterValues& parameters) {
  if (api::Status st = Require(actor, Permission::kOperateBench, "starting a run"); !st.ok()) {
    return st;
  }
  const protocols::ProtocolDescription* description = protocols::FindProtocol(protocol);
  if (description == nullptr) return api::Status::NotFound("unknown protocol '" + protocol + "'");
  for (const auto& [name, value] : parameters) {
    if (!std::isfinite(value)) {
      return api::Status::InvalidArgument("must be finite", "parameters." + name);
    }
  }
  return description;
}

// tracking's uploaded target, at the control's 200 Hz.
api::Status ResampleUploadedTarget(const TargetSamples& target, protocols::StartRequest& request) {
  auto resampled = api::CallModel(
      [&] { return model::ResampleTarget(target.t_s, target.angle_deg, 200.0); }, "target_samples");
  if (!resampled.ok()) return resampled.status();
  request.target_angle_deg = *std::move(resampled);
  if (request.target_angle_deg.size() > 600 * 200 + 1) {
    return api::Status::InvalidArgument("longer than 600 s", "target_samples");
  }
  return api::Status::Ok();
}

// A tracking run may name the leg's set to invert (parameter_set_id; 0: its
// approved set): it must be one of this session's leg's sets that a
// clinician approved (docs/SAFETY.md), now or earlier.
api::Status ChooseParameterSet(storage::Database& db, const SessionContext& context,
                               const protocols::ParameterValues& parameters,
                               protocols::StartRequest& request) {
  const auto it = parameters.find("parameter_set_id");
  if (it == parameters.end() || !(it->second >= 1.0) || !std::isfinite(it->second)) {
    return api::Status::Ok();
  }
  const auto id = static_cast<std::int64_t>(it->second);
  api::Result<storage::StoredParameterSet> chosen = storage::ParameterSetRepository(db).Get(id);
  if (!chosen.ok()) {
    if (chosen.status().code() != api::ErrorCode::kNotFound) return chosen.status();
    return api::Status::InvalidArgument("no parameter set " + std::to_string(id),
                                        "parameters.parameter_set_id");
  }
  if (chosen->summary.subject_id != context.session.subject_id ||
      chosen->summary.leg_id != context.session.leg_id) {
    return api::Status::InvalidArgument(
        "parameter set " + std::to_string(id) + " belongs to another subject or leg",
        "parameters.parameter_set_id");
  }
  api::Result<std::vector<storage::Approval>> approvals =
      storage::ParameterSetRepository(db).Approvals(id);
  if (!approvals.ok()) return approvals.status();
  if (approvals->empty()) {
    return api::Status::FailedPrecondition(
        "parameter set " + std::to_string(id) +
        " was never approved: a clinician approves it first (POST /api/v1/parameter-sets/" +
        std::to_string(id) + "/approve, or `fesbench params approve " + std::to_string(id) +
        " --note TEXT`)");
  }
  request.subject.parameter_set = chosen->params;
  request.subject.parameter_set_id = id;
  return api::Status::Ok();
}

}  // namespace

api::Status RunService::CheckBenchFree() {
  if (owner_.busy()) {
    return api::Status::Conflict("the bench is held by a run of " + owner_.owner());
  }
  if (const std::shared_ptr<LiveRun> previous = runs_.Current()) {
    if (!runs_.Locked([&] { return previous->final; })) {
      return api::Status::Conflict("the previous run is still being stored");
    }
  }
  if (owner_.safe_bench().estopped() || bench_.HardwareEStopped()) {
    return api::Status::Conflict("e-stop latched: clear it first");
  }
  return api::Status::Ok();
}

api::Result<protocols::StartRequest> RunService::BuildStartRequest(
    const SessionContext& context, const std::string& protocol,
    const protocols::ParameterValues& parameters, const std::optional<std::string>& ceiling_reason,
    const TargetSamples* target) {
  protocols::StartRequest request;
  request.protocol = protocol;
  request.parameters = parameters;
  request.subject = context.subject;
  request.subject.ceiling_above_max = ceiling_reason;
  // The stimulator's limit bounds every ceiling, explicit or not.
  if (const auto it = parameters.find("ceiling_ma");
      it != parameters.end() && it->second > bench_.limits().max_stim_ma) {
    return api::Status::InvalidArgument(
        "above the stimulator's limit " + FormatNumber(bench_.limits().max_stim_ma) + " mA",
        "parameters.ceiling_ma");
  }
  if (target != nullptr) {
    if (api::Status st = ResampleUploadedTarget(*target, request); !st.ok()) return st;
  }
  if (api::Status st = ChooseParameterSet(db_, context, parameters, request); !st.ok()) return st;
  return request;
}

api::Result<storage::Run> RunService::CreateRunRecord(
    const Actor& actor, std::int64_t session_id, const std::string& protocol,
    const protocols::ParameterValues& parameters, const protocols::Plan& plan,
    const SessionContext& context, const std::optional<std::string>& ceiling_reason) {
  nlohmann::json params_json = nlohmann::json::object();
  for (const auto& [k, v] : plan.parameters) params_json[k] = v;
  storage::NewRun new_run;
  new_run.protocol_name = protocol;
  new_run.protocol_version = std::to_string(plan.protocol_version);
  new_run.parameters_json = params_json.dump();
  return db_.Write([&](storage::Connection&) -> api::Result<storage::Run> {
    api::Result<storage::Run> r = storage::SessionRepository(db_).CreateRun(session_id, new_run);
    if (!r.ok()) return r;
    std::string summary =
        "session " + std::to_string(session_id) + ", " + protocol + " v" + new_run.protocol_version;
    for (const auto& [k, v] : parameters) summary += ", " + k + "=" + FormatNumber(v);
    if (api::Status a = AppendAudit(db_, actor, "run.start", RunTarget(r->id), summary, "ok"); !a.ok()) {
      return a;
    }
    if (ceiling_reason) {
      const std::string why =
          "tolerance test ceiling " + FormatNumber(plan.parameters.at("ceiling_ma")) +
          " mA above the session's recorded max tolerated " +
          FormatNumber(context.subject.max_tolerated_ma) + " mA; reason: " + *ceiling_reason;
      if (api::Status a = AppendAudit(db_, actor, "run.ceiling_above_max", RunTarget(r->id), why, "ok");
          !a.ok()) {
        return a;
      }
    }
    return r;
  });
}

std::shared_ptr<LiveRun> RunService::RegisterLiveRun(
    const Actor& actor, const storage::Run& created, const protocols::Plan& plan,
    const protocols::ProtocolDescription& description, const SessionContext& context,
    std::int64_t session_id, const std::string& protocol) {
  auto run = std::make_shared<LiveRun>();
  run->run_id = created.id;
  run->subject_id = context.session.subject_id;
  run->leg_id = context.session.leg_id;
  run->actor = actor;
  run->mode = description.bench_mode;
  run->prior_parameter_set_id = context.parameter_set_id;
  RunView& v = run->view;
  v.run_id = created.id;
  v.session_id = session_id;
  v.protocol = protocol;
  v.protocol_version = plan.protocol_version;
  v.parameters = plan.parameters;
  v.used_parameter_set_id = api::UsedParameterSetOf(plan.parameters);
  v.state = RunState::kQueued;
  v.owner = actor.user_name;
  v.owner_user_id = actor.user_id;
  v.created_at = created.created_at;
  v.progress.bench_total_s = v.progress.bench_planned_s = plan.duration_s();
  v.progress.eta_s = config_.time_scale > 0.0 ? plan.duration_s() / config_.time_scale : 0.0;
  v.live = true;
  runs_.Add(run);
  HubItem queued;
  queued.kind = HubItem::Kind::kState;
  queued.run_id = run->run_id;
  queued.state = RunState::kQueued;
  queued.progress = v.progress;
  hub_.Publish(std::move(queued));
  return run;
}

api::Result<RunView> RunService::StartImpl(const Actor& actor, std::int64_t session_id,
                                           const std::string& protocol,
                                           const protocols::ParameterValues& parameters,
                                           const std::optional<std::string>& ceiling_reason,
                                           const TargetSamples* target) {
  api::Result<const protocols::ProtocolDescription*> description =
      CheckStartRequest(actor, protocol, parameters);
  if (!description.ok()) return description.status();

  std::lock_guard start_lock(start_mu_);
  {
    std::lock_guard lock(mu_);
    if (shutting_down_) return api::Status::Unavailable("the server is shutting down");
    if (!bench_lost_.empty()) return api::Status::Unavailable(bench_lost_);
  }
  api::Result<SessionContext> context = LoadSessionContext(db_, session_id, bench_.limits());
  if (!context.ok()) return context.status();
  if (!context->has_stimulation_limits &&
      (*description)->kind != protocols::ProtocolKind::kTolerance) {
    return api::Status::FailedPrecondition(
        "session " + std::to_string(session_id) +
        " has no threshold and max tolerated amplitude: record them (tolerance_test) first");
  }
  if (api::Status free = CheckBenchFree(); !free.ok()) return free;

  api::Result<protocols::StartRequest> request =
      BuildStartRequest(*context, protocol, parameters, ceiling_reason, target);
  if (!request.ok()) return request.status();
  request->client = actor.user_name;
  api::Result<protocols::Plan> plan = owner_.Prepare(*request);
  if (!plan.ok()) return plan.status();

  api::Result<storage::Run> created =
      CreateRunRecord(actor, session_id, protocol, parameters, *plan, *context, ceiling_reason);
  if (!created.ok()) return created.status();
  std::shared_ptr<LiveRun> run =
      RegisterLiveRun(actor, *created, *plan, **description, *context, session_id, protocol);

  run->on_bench = true;
  api::Status started = owner_.Start(*request, recorder_.Observe(run));
  if (!started.ok()) {
    run->on_bench = false;
    // Refused at the last moment (e.g. an e-stop in between): the run failed.
    recorder_.Refused(run, started.message());
    return started;
  }
  return runs_.Locked([&] { return run->view; });
}

api::Status RunService::CheckCurrent(std::int64_t run_id, std::shared_ptr<LiveRun>* out) {
  std::shared_ptr<LiveRun> run = FindLive(run_id);
  if (!run) {
    api::Result<storage::Run> stored = storage::SessionRepository(db_).GetRun(run_id);
    if (!stored.ok()) return stored.status();
    const std::string& bench = db_.options().bench_id;
    if (!stored->bench_id.empty() && stored->bench_id != bench && !api::IsFinal(stored->state)) {
      return api::Status::Conflict("run " + std::to_string(run_id) + " runs on bench '" +
                                   stored->bench_id + "', not on this server's bench '" + bench +
                                   "': send this to that bench's server");
    }
    return api::Status::Conflict("run " + std::to_string(run_id) + " is not in progress (" +
                                 std::string(api::RunStateName(stored->state)) + ")");
  }
  const bool current = run == runs_.Current();
  const auto [final, state] = runs_.Locked([&] { return std::pair(run->final, run->view.state); });
  if (final || !current) {
    return api::Status::Conflict("run " + std::to_string(run_id) + " is not in progress (" +
                                 std::string(protocols::RunStateName(state)) + ")");
  }
  *out = std::move(run);
  return api::Status::Ok();
}

api::Status RunService::Cancel(const Actor& actor, std::int64_t run_id) {
  return Guarded("Cancel", "cancelling the run failed", [&]() -> api::Status {
    if (api::Status st = Require(actor, Permission::kOperateBench, "cancelling a run"); !st.ok()) {
      return st;
    }
    std::shared_ptr<LiveRun> run;
    if (api::Status st = CheckCurrent(run_id, &run); !st.ok()) return st;
    if (api::Status st = owner_.Cancel("cancelled by " + actor.user_name); !st.ok()) {
      return api::Status::Conflict("run " + std::to_string(run_id) + " is no longer running");
    }
    if (api::Status a = AppendAudit(db_, actor, "run.cancel", RunTarget(run_id), "cancel", "ok"); !a.ok()) {
      Log("audit of cancel: " + a.ToString());
    }
    return api::Status::Ok();
  });
}

api::Status RunService::StopWithResult(const Actor& actor, std::int64_t run_id) {
  return Guarded("StopWithResult", "stopping the run failed", [&]() -> api::Status {
    if (api::Status st = Require(actor, Permission::kOperateBench, "stopping a run"); !st.ok()) {
      return st;
    }
    std::shared_ptr<LiveRun> run;
    if (api::Status st = CheckCurrent(run_id, &run); !st.ok()) return st;
    if (api::Status st = owner_.Stop(); !st.ok()) {
      return api::Status::Conflict("run " + std::to_string(run_id) + " is no longer running");
    }
    if (api::Status a = AppendAudit(db_, actor, "run.stop", RunTarget(run_id), "stop with result", "ok");
        !a.ok()) {
      Log("audit of stop: " + a.ToString());
    }
    return api::Status::Ok();
  });
}

api::Status RunService::Heartbeat(const Actor& actor, std::int64_t run_id) {
  return Guarded("Heartbeat", "heartbeat failed", [&]() -> api::Status {
    std::shared_ptr<LiveRun> run;
    if (api::Status st = CheckCurrent(run_id, &run); !st.ok()) return st;
    if (run->actor.user_id != actor.user_id || run->actor.user_name != actor.user_name) {
      return api::Status(api::ErrorCode::kPermissionDenied,
                         "only " + run->actor.user_name + ", who started run " +
                             std::to_string(run_id) + ", controls it");
    }
    owner_.Heartbeat();
    return api::Status::Ok();
  });
}

api::Status RunService::EStop(const Actor& actor, std::string_view source) {
  const std::string who =
      (source.empty() ? std::string("unknown source") : std::string(source)) + " (" +
      (actor.user_name.empty() ? std::string("unknown") : actor.user_name) + ")";
  // Act first: nothing may delay the e-stop (docs/SAFETY.md).
  owner_.EStop(who);
  try {
    std::string target = "bench";
    {
      std::lock_guard lock(mu_);
      estop_source_ = who;
    }
    if (const std::shared_ptr<LiveRun> run = runs_.Current();
        run && !runs_.Locked([&] { return run->final; })) {
      target = RunTarget(run->run_id);
    }
    // The latch outlives this process: stored with its audit row, before the answer.
    const api::Status stored = db_.Write([&](storage::Connection&) -> api::Status {
      if (api::Status st = storage::EStopLatchRepository(db_).RecordLatched(who, actor.user_name);
          !st.ok()) {
        return st;
      }
      return AppendAudit(db_, actor, "bench.estop", target, "e-stop from " + who, "ok");
    });
    if (!stored.ok()) Log("storing the e-stop latch: " + stored.ToString());
  } catch (const std::exception& e) {
    Log(std::string("EStop (after latching): ") + e.what());
  }
  return api::Status::Ok();
}

api::Status RunService::ClearEStop(const Actor& actor) {
  return Guarded("ClearEStop", "clearing the e-stop failed", [&]() -> api::Status {
    if (api::Status st = Require(actor, Permission::kOperateBench, "clearing the e-stop");
        !st.ok()) {
      return st;
    }
    if (owner_.busy()) {
      return api::Status::Conflict("a run is still stopping; clear the e-stop after it ends");
    }
    {
      std::lock_guard lock(mu_);
      if (!bench_lost_.empty()) return api::Status::Unavailable(bench_lost_);
    }
    // While latched no run can start, so the bench stays idle from here on.
    const bool was = owner_.safe_bench().estopped() || bench_.HardwareEStopped();
    // Stored and audited first, in one transaction: if that fails the latch
    // stays set in both places and the person can try again.
    const api::Status stored = db_.Write([&](storage::Connection&) -> api::Status {
      storage::EStopLatchRepository latch(db_);
      api::Result<std::optional<storage::LatchedEStop>> current = latch.Current();
      if (!current.ok()) return current.status();
      if (*current || was) {
        if (api::Status st = latch.RecordCleared(actor.user_name); !st.ok()) return st;
      }
      return AppendAudit(db_, actor, "bench.clear_estop", "bench",
                   *current || was ? "e-stop cleared" : "e-stop was not latched", "ok");
    });
    if (!stored.ok()) return stored;
    if (api::Status st = owner_.ClearEStop("cleared by " + actor.user_name); !st.ok()) return st;
    // A hardware e-stop (the bench button) is cleared with it.
    if (bench_.HardwareEStopped()) bench_.ClearHardwareEStop();
    {
      std::lock_guard lock(mu_);
      estop_source_.clear();
    }
    return api::Status::Ok();
  });
}

void RunService::LoseBench(const std::string& reason) {
  {
    // Refused first, so a start in progress either sees it or is stopped
    // by the e-stop below (BenchOwner refuses to start while latched).
    std::lock_guard lock(mu_);
    const bool latched_already = !bench_lost_.empty();  // ClearEStop is refused since
    bench_lost_ = reason.empty() ? std::string("this server lost its bench lock") : reason;
    if (latched_already) return;
  }
  (void)EStop(SystemActor(), "bench lock lost");
}

void RunService::RegainBench() {
  std::lock_guard lock(mu_);
  bench_lost_.clear();
}

api::Result<Recovery> RunService::RecoverAfterRestart() {
  const Actor system = SystemActor();
  Recovery out;
  api::Result<std::vector<storage::Run>> unfinished =
      storage::SessionRepository(db_).ListUnfinishedRuns();
  if (!unfinished.ok()) return unfinished.status();
  for (const storage::Run& run : *unfinished) {
    if (FindLive(run.id)) continue;  // never ours: called before any start
    const api::RunOutcome outcome =
        protocols::FailOutcome(api::RunOutcome{}, run.state, kStoppedDuringRunReason);
    const api::Status closed = db_.Write([&](storage::Connection&) -> api::Status {
      api::Result<storage::Run> r = storage::SessionRepository(db_).RecordRunState(
          run.id, outcome.state, outcome.reason, std::nullopt, &outcome);
      if (!r.ok()) return r.status();
      return AppendAudit(db_, system, "run.recovered", RunTarget(run.id),
                   std::string("was ") + std::string(api::RunStateName(run.state)) + ": " +
                       kStoppedDuringRunReason,
                   "ok");
    });
    if (!closed.ok()) return closed;
    out.failed_run_ids.push_back(run.id);
  }

  api::Result<std::optional<storage::LatchedEStop>> latched =
      storage::EStopLatchRepository(db_).Current();
  if (!latched.ok()) return latched.status();
  if (*latched) {
    const std::string who =
        (*latched)->source.empty() ? std::string("e-stop before the restart") : (*latched)->source;
    owner_.EStop(who);
    {
      std::lock_guard lock(mu_);
      estop_source_ = who;
    }
    if (api::Status a = AppendAudit(db_, system, "bench.estop_restored", "bench",
                              "e-stop latched since " + api::FormatUtc((*latched)->at) +
                                  " by " + who + ": latched again at start",
                              "ok");
        !a.ok()) {
      return a;
    }
    out.estop_source = who;
  }
  return out;
}

api::Status RunService::WithIdleBench(const std::function<api::Status()>& fn) {
  return Guarded("WithIdleBench", "changing the bench failed", [&]() -> api::Status {
    std::lock_guard start_lock(start_mu_);
    {
      std::lock_guard lock(mu_);
      if (shutting_down_) return api::Status::Unavailable("the server is shutting down");
    }
    if (owner_.busy()) {
      return api::Status::Conflict("a run of " + owner_.owner() + " holds the bench");
    }
    return fn();
  });
}

void RunService::Shutdown() {
  std::lock_guard start_lock(start_mu_);
  {
    std::lock_guard lock(mu_);
    shutting_down_ = true;
  }
  try {
    if (owner_.busy()) (void)owner_.Cancel("server shutting down");
    (void)owner_.Wait();  // stimulation is 0 once the runner returns
  } catch (const std::exception& e) {
    Log(std::string("Shutdown: ") + e.what());
  }
  recorder_.Stop();
}

}  // namespace fesbench::server::services
