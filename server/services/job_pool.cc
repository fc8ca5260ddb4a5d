#include "server/services/job_pool.h"

#include <algorithm>
#include <exception>
#include <utility>

namespace fesbench::server::services {

nlohmann::json JobToJson(const JobRecord& job) {
  const auto stamp = [](const std::optional<api::UtcTime>& t) {
    return t ? nlohmann::json(api::FormatUtc(*t)) : nlohmann::json(nullptr);
  };
  nlohmann::json j = {
      {"id", job.id},
      {"kind", job.kind},
      {"state", JobStateName(job.state)},
      {"submitted_by",
       {{"user_id", job.actor.user_id},
        {"user_name", job.actor.user_name},
        {"role", RoleName(job.actor.role)}}},
      {"submitted_at_utc", api::FormatUtc(job.submitted_at)},
      {"started_at_utc", stamp(job.started_at)},
      {"finished_at_utc", stamp(job.finished_at)},
  };
  if (job.state == JobState::kDone) j["result"] = job.result;
  if (job.state == JobState::kFailed) {
    j["error"] = api::ErrorToJson(job.error);
  }
  return j;
}

JobPool::JobPool(JobPoolConfig config) : config_(std::move(config)) {
  if (config_.clock == nullptr) config_.clock = api::Clock::Real();
  config_.workers = std::clamp(config_.workers, 1, 64);
  config_.queue_capacity = std::max<std::size_t>(config_.queue_capacity, 1);
  config_.history = std::max<std::size_t>(config_.history, 1);
  workers_.reserve(static_cast<std::size_t>(config_.workers));
  for (int i = 0; i < config_.workers; ++i) workers_.emplace_back([this] { WorkerLoop(); });
}

JobPool::~JobPool() { Shutdown(/*drain=*/false); }

api::UtcTime JobPool::Now() const {
  return config_.clock->UtcNow();
}

api::Result<std::int64_t> JobPool::Submit(std::string kind, const Actor& actor, JobFunction fn) {
  if (kind.empty()) return api::Status::InvalidArgument("job kind must not be empty", "kind");
  if (!fn) return api::Status::InvalidArgument("job has no function", "kind");
  const api::UtcTime now = Now();
  std::lock_guard lock(mu_);
  if (stopping_) return api::Status::Unavailable("job pool shutting down");
  if (queue_.size() >= config_.queue_capacity) {
    return api::Status::Unavailable("job queue full (" + std::to_string(config_.queue_capacity) +
                                    " jobs waiting); retry later");
  }
  const std::int64_t id = next_id_++;
  JobRecord record;
  record.id = id;
  record.kind = std::move(kind);
  record.actor = actor;
  record.submitted_at = now;
  records_.emplace(id, std::move(record));
  functions_.emplace(id, std::move(fn));
  queue_.push_back(id);
  wake_.notify_one();
  return id;
}

api::Result<JobRecord> JobPool::Get(std::int64_t id) const {
  std::lock_guard lock(mu_);
  const auto it = records_.find(id);
  if (it == records_.end()) return api::Status::NotFound("no job " + std::to_string(id));
  return it->second;
}

std::vector<JobRecord> JobPool::List(std::size_t limit) const {
  std::lock_guard lock(mu_);
  std::vector<JobRecord> out;
  for (auto it = records_.rbegin(); it != records_.rend() && out.size() < limit; ++it) {
    out.push_back(it->second);
  }
  return out;
}

std::size_t JobPool::queued() const {
  std::lock_guard lock(mu_);
  return queue_.size();
}

std::size_t ApproximateJsonBytes(const nlohmann::json& value) {
  std::size_t bytes = sizeof(nlohmann::json);
  if (value.is_string()) {
    bytes += sizeof(std::string) + value.get_ref<const std::string&>().size();
  } else if (value.is_array()) {
    bytes += sizeof(nlohmann::json::array_t);
    for (const auto& item : value) bytes += ApproximateJsonBytes(item);
  } else if (value.is_object()) {
    bytes += sizeof(nlohmann::json::object_t);
    for (const auto& [key, item] : value.items()) {
      bytes += 48 + key.size() + ApproximateJsonBytes(item);  // a map node and its key
    }
  }
  return bytes;
}

void JobPool::Forget() {
  while (!finished_order_.empty() &&
         (finished_order_.size() > config_.history ||
          (finished_bytes_ > config_.history_bytes && finished_order_.size() > 1))) {
    auto it = records_.find(finished_order_.front());
    finished_bytes_ -= std::min(finished_bytes_, it->second.result_bytes);
    records_.erase(it);
    finished_order_.pop_front();
  }
}

void JobPool::WorkerLoop() {
  for (;;) {
    std::int64_t id = 0;
    JobFunction fn;
    {
      std::unique_lock lock(mu_);
      wake_.wait(lock, [this] { return !queue_.empty() || stopping_; });
      if (queue_.empty() || (stopping_ && !drain_)) return;
      id = queue_.front();
      queue_.pop_front();
      fn = std::move(functions_.at(id));
      functions_.erase(id);
      JobRecord& r = records_.at(id);
      r.state = JobState::kRunning;
      r.started_at = Now();
    }
    api::Result<nlohmann::json> out = api::Status::Internal("job produced no result");
    try {
      out = fn();
    } catch (const std::exception& e) {
      out = api::Status::Internal(std::string("job threw: ") + e.what());
    } catch (...) {
      out = api::Status::Internal("job threw a non-standard exception");
    }
    const api::UtcTime finished = Now();
    const std::size_t result_bytes = out.ok() ? ApproximateJsonBytes(*out) : 0;
    std::lock_guard lock(mu_);
    JobRecord& r = records_.at(id);
    r.finished_at = finished;
    if (out.ok()) {
      r.state = JobState::kDone;
      r.result = std::move(out).value();
      r.result_bytes = result_bytes;
      finished_bytes_ += result_bytes;
    } else {
      r.state = JobState::kFailed;
      r.error = out.status();
    }
    finished_order_.push_back(id);
    Forget();
  }
}

void JobPool::Shutdown(bool drain) {
  std::lock_guard join_lock(join_mu_);
  {
    std::lock_guard lock(mu_);
    if (!stopping_) {
      stopping_ = true;
      drain_ = drain;
    }
    if (!drain_) {
      const api::UtcTime now = Now();
      for (const std::int64_t id : queue_) {
        JobRecord& r = records_.at(id);
        r.state = JobState::kFailed;
        r.finished_at = now;
        r.error = api::Status::Unavailable("cancelled: job pool shutting down");
        functions_.erase(id);
        finished_order_.push_back(id);
      }
      queue_.clear();
      Forget();
    }
  }
  wake_.notify_all();
  for (std::thread& t : workers_) {
    if (t.joinable()) t.join();
  }
  workers_.clear();
}

}  // namespace fesbench::server::services
