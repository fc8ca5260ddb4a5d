#include "server/bench/device_keeper.h"

#include <utility>

namespace fesbench::server {

void DeviceKeeper::Start(std::chrono::milliseconds period, std::function<api::Status()> duty) {
  if (thread_.joinable()) return;
  thread_ = std::thread([this, period, duty = std::move(duty)] {
    std::unique_lock lock(mu_);
    while (!cv_.wait_for(lock, period, [&] { return stop_; })) {
      lock.unlock();
      const bool alive = duty().ok();
      lock.lock();
      if (!alive) return;
    }
  });
}

void DeviceKeeper::Stop() {
  if (!thread_.joinable()) return;
  {
    std::lock_guard lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

}  // namespace fesbench::server
