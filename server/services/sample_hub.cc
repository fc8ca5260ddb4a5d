#include "server/services/sample_hub.h"

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <utility>
#include <vector>

namespace fesbench::server::services {

struct Subscription::Queue {
  explicit Queue(SubscribeOptions o) : options(std::move(o)) {}
  const SubscribeOptions options;
  mutable std::mutex mu;
  std::condition_variable cv;
  std::deque<HubItemPtr> items;
  std::uint64_t dropped = 0;
  bool closed = false;

  // Never waits for the reader beyond its short pop: drop the oldest when full.
  void Push(HubItemPtr item) {
    {
      std::lock_guard lock(mu);
      if (closed) return;
      while (items.size() >= std::max<std::size_t>(1, options.capacity)) {
        items.pop_front();
        ++dropped;
      }
      items.push_back(std::move(item));
    }
    cv.notify_one();
  }
  void Close() {
    {
      std::lock_guard lock(mu);
      closed = true;
    }
    cv.notify_all();
  }
  bool Accepts(const HubItem& item) const {
    return (!options.run_id || item.run_id == *options.run_id) &&
           (!options.kind || item.kind == *options.kind) &&
           !(options.stored_sets_only && item.approval);
  }
};

namespace detail {

struct HubCore {
  mutable std::mutex mu;
  std::vector<std::shared_ptr<Subscription::Queue>> queues;
  std::uint64_t next_seq = 1;
  std::optional<HubItem> current;  // last state of the current run, with its last progress
  bool closed = false;
  std::uint64_t dropped_removed = 0;  // drops of subscriptions already gone

  void Remove(const Subscription::Queue* queue) {
    std::lock_guard lock(mu);
    const auto it =
        std::find_if(queues.begin(), queues.end(), [&](const auto& q) { return q.get() == queue; });
    if (it == queues.end()) return;
    {
      std::lock_guard ql((*it)->mu);
      dropped_removed += (*it)->dropped;
    }
    queues.erase(it);
  }
};

}  // namespace detail

// --- Subscription -------------------------------------------------------------

Subscription::Subscription(std::shared_ptr<Queue> queue, std::shared_ptr<detail::HubCore> core)
    : queue_(std::move(queue)), core_(std::move(core)) {}

Subscription::~Subscription() {
  queue_->Close();
  core_->Remove(queue_.get());
}

HubItemPtr Subscription::Next(std::chrono::milliseconds timeout) {
  std::unique_lock lock(queue_->mu);
  queue_->cv.wait_for(lock, timeout, [&] { return !queue_->items.empty() || queue_->closed; });
  if (queue_->items.empty()) return nullptr;
  HubItemPtr item = std::move(queue_->items.front());
  queue_->items.pop_front();
  return item;
}

std::uint64_t Subscription::dropped() const {
  std::lock_guard lock(queue_->mu);
  return queue_->dropped;
}

bool Subscription::closed() const {
  std::lock_guard lock(queue_->mu);
  return queue_->closed;
}

void Subscription::Close() { queue_->Close(); }

// --- SampleHub ------------------------------------------------------------------

SampleHub::SampleHub() : core_(std::make_shared<detail::HubCore>()) {}

SampleHub::~SampleHub() { Close(); }

std::unique_ptr<Subscription> SampleHub::Subscribe(SubscribeOptions options) {
  auto queue = std::make_shared<Subscription::Queue>(std::move(options));
  std::lock_guard lock(core_->mu);
  if (core_->closed) {
    queue->closed = true;
  } else {
    HubItem first;
    if (core_->current) first = *core_->current;
    first.kind = HubItem::Kind::kState;
    if (queue->Accepts(first)) queue->items.push_back(std::make_shared<const HubItem>(first));
    core_->queues.push_back(queue);
  }
  return std::unique_ptr<Subscription>(new Subscription(std::move(queue), core_));
}

std::uint64_t SampleHub::Publish(HubItem item) {
  std::lock_guard lock(core_->mu);
  item.seq = core_->next_seq++;
  std::optional<HubItem>& current = core_->current;
  switch (item.kind) {
    case HubItem::Kind::kState:
    case HubItem::Kind::kEnd:
      if (!current || current->run_id != item.run_id) {
        current = HubItem{};
        current->run_id = item.run_id;
      }
      current->state = item.state;
      current->reason = item.reason;
      current->seq = item.seq;
      break;
    case HubItem::Kind::kProgress:
      if (current && current->run_id == item.run_id) current->progress = item.progress;
      break;
    case HubItem::Kind::kSamples:
    case HubItem::Kind::kTrial:
    case HubItem::Kind::kParameterSet:
      break;
  }
  const auto shared = std::make_shared<const HubItem>(std::move(item));
  for (const auto& q : core_->queues) {
    if (q->Accepts(*shared)) q->Push(shared);
  }
  return shared->seq;
}

void SampleHub::Close() {
  std::lock_guard lock(core_->mu);
  core_->closed = true;
  for (const auto& q : core_->queues) q->Close();
}

std::size_t SampleHub::subscriber_count() const {
  std::lock_guard lock(core_->mu);
  return core_->queues.size();
}

std::uint64_t SampleHub::total_dropped() const {
  std::lock_guard lock(core_->mu);
  std::uint64_t n = core_->dropped_removed;
  for (const auto& q : core_->queues) {
    std::lock_guard ql(q->mu);
    n += q->dropped;
  }
  return n;
}

ParameterSetEvents::ParameterSetEvents(storage::Database& db, SampleHub& hub) : db_(db) {
  db_.SetParameterSetListener([&hub](const storage::Database::ParameterSetStored& stored) {
    HubItem item;
    item.kind = HubItem::Kind::kParameterSet;
    item.parameter_set_id = stored.id;
    item.subject_id = stored.subject_id;
    item.leg_id = stored.leg_id;
    item.approval = stored.approval;
    hub.Publish(std::move(item));
  });
}

ParameterSetEvents::~ParameterSetEvents() { db_.SetParameterSetListener({}); }

}  // namespace fesbench::server::services
