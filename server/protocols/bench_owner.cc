#include "server/protocols/bench_owner.h"

#include "server/protocols/model_gate.h"

namespace fesbench::server::protocols {

BenchOwner::BenchOwner(Bench& bench, BenchOwnerOptions options)
    : options_(std::move(options)), safe_(bench, log_.sink(), options_.clock) {}

BenchOwner::~BenchOwner() {
  {
    std::lock_guard lock(mu_);
    if (runner_ && busy_) runner_->Cancel("server shutting down");
  }
  if (thread_.joinable()) thread_.join();
}

api::Result<Plan> BenchOwner::Prepare(const StartRequest& request) const {
  api::Result<Plan> plan = MakePlan(request.protocol, request.parameters, request.subject,
                                     request.target_angle_deg);
  if (!plan.ok()) return plan;
  if (api::Status gate = CheckModelGate(*plan, request.subject, safe_.bench_limits().pulse_rate_hz,
                                          safe_.bench_limits().max_stop_impact_deg_s);
      !gate.ok()) {
    return gate;
  }
  return plan;
}

void BenchOwner::JoinFinished() {
  // Called with mu_ not held: the run thread takes mu_ when it finishes.
  std::lock_guard lock(join_mu_);
  if (thread_.joinable()) thread_.join();
}

api::Status BenchOwner::Start(const StartRequest& request, std::shared_ptr<RunObserver> observer) {
  {
    std::lock_guard lock(mu_);
    if (busy_) {
      return api::Status::Conflict("the bench is held by a run of client " + owner_);
    }
  }
  if (safe_.estopped()) return api::Status::Conflict("e-stop latched: clear it first");
  api::Result<Plan> plan = Prepare(request);
  if (!plan.ok()) return plan.status();
  JoinFinished();
  std::lock_guard lock(mu_);
  if (busy_) return api::Status::Conflict("the bench is held by a run of client " + owner_);
  busy_ = true;
  owner_ = request.client;
  last_.reset();
  observer_ = std::move(observer);
  RunnerOptions ro = options_.runner;
  ro.clock = options_.clock;
  runner_ = std::make_unique<ProtocolRunner>(safe_, &log_, observer_.get(), ro);
  thread_ = std::thread([this, p = std::move(plan).value(), subject = request.subject] {
    RunResult r = runner_->Run(p, subject);
    std::lock_guard l(mu_);
    last_ = std::move(r);
    busy_ = false;
    owner_.clear();
    cv_.notify_all();
  });
  return api::Status::Ok();
}

api::Status BenchOwner::Cancel(const std::string& reason) {
  std::lock_guard lock(mu_);
  if (!busy_ || !runner_) return api::Status::NotFound("no run in progress");
  runner_->Cancel(reason);
  return api::Status::Ok();
}

api::Status BenchOwner::Stop() {
  std::lock_guard lock(mu_);
  if (!busy_ || !runner_) return api::Status::NotFound("no run in progress");
  runner_->Stop();
  return api::Status::Ok();
}

std::optional<RunResult> BenchOwner::Wait() {
  {
    std::unique_lock lock(mu_);
    cv_.wait(lock, [&] { return !busy_; });
  }
  JoinFinished();
  std::lock_guard lock(mu_);
  std::optional<RunResult> out = std::move(last_);
  last_.reset();
  return out;
}

bool BenchOwner::busy() const {
  std::lock_guard lock(mu_);
  return busy_;
}

std::string BenchOwner::owner() const {
  std::lock_guard lock(mu_);
  return owner_;
}

api::Status BenchOwner::ClearEStop(const std::string& source) {
  if (busy())
    return api::Status::Conflict("a run is still stopping; clear the e-stop after it ends");
  safe_.ClearEStop(source);
  return api::Status::Ok();
}

}  // namespace fesbench::server::protocols
