#include "server/services/live_runs.h"

namespace fesbench::server::services {

void LiveRuns::Add(std::shared_ptr<LiveRun> run) {
  std::lock_guard lock(mu_);
  current_run_id_ = run->run_id;
  runs_[run->run_id] = std::move(run);
}

std::shared_ptr<LiveRun> LiveRuns::Find(std::int64_t run_id) const {
  std::lock_guard lock(mu_);
  const auto it = runs_.find(run_id);
  return it == runs_.end() ? nullptr : it->second;
}

std::shared_ptr<LiveRun> LiveRuns::Current() const {
  std::lock_guard lock(mu_);
  const auto it = runs_.find(current_run_id_);
  return it == runs_.end() ? nullptr : it->second;
}

api::RunView LiveRuns::WaitFinal(const LiveRun& run, std::chrono::milliseconds timeout) const {
  std::unique_lock lock(mu_);
  final_cv_.wait_for(lock, timeout, [&] { return run.final; });
  return run.view;
}

void LiveRuns::Finalise(LiveRun& run, const std::function<void(api::RunView&)>& fn) {
  {
    std::lock_guard lock(mu_);
    fn(run.view);
    run.final = true;
    std::size_t finished = 0;
    for (const auto& [id, r] : runs_) finished += r->final ? 1 : 0;
    for (auto it = runs_.begin(); it != runs_.end() && finished > finished_kept_;) {
      if (it->second->final && it->first != current_run_id_) {
        it = runs_.erase(it);
        --finished;
      } else {
        ++it;
      }
    }
  }
  final_cv_.notify_all();
}

}  // namespace fesbench::server::services
