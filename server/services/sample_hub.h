#pragma once

/// @file
/// Fan-out of the server's live events (docs/API.md: runs/{id}/stream,
/// fesbench/bench/samples): state changes, progress, sample batches, stored
/// trials and the end of each run, and every stored parameter set, go to any
/// number of subscribers (SSE viewers, the DDS front end).
///
/// Publishing never blocks on a subscriber: each subscriber has a bounded
/// queue; when it is full the oldest item is dropped and counted, so a slow
/// or vanished subscriber costs the publisher (the run's control loop) one
/// short lock per subscriber and nothing else. Items are immutable and shared
/// between subscribers (published once, never copied per subscriber).
/// Thread-safe.

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "server/protocols/runner.h"
#include "storage/database.h"

namespace fesbench::server::services {

/// One event of a run (api/run.h).
using HubItem = api::RunEvent;

using HubItemPtr = std::shared_ptr<const HubItem>;

struct SubscribeOptions {
  /// Queue length in items (≥ 1); when full the oldest is dropped. At the
  /// default batching (40 samples, 0.1 s progress) a real-time run makes
  /// about 15 items/s, so 1024 items are over a minute of slack.
  std::size_t capacity = 1024;
  /// Only items of this run (plus the initial state item); nullopt = all.
  std::optional<std::int64_t> run_id;
  /// Only items of this kind (the initial state item too only if kState);
  /// nullopt = all.
  std::optional<HubItem::Kind> kind;
  /// Leave out kParameterSet items that are approvals (the SSE stream of
  /// stored sets).
  bool stored_sets_only = false;
};

class SampleHub;
namespace detail {
struct HubCore;  // the hub's shared state; subscriptions keep it alive
}

/// A subscription (RAII: destroying it unsubscribes). Read it from one
/// thread; Close may be called from any thread.
class Subscription {
 public:
  ~Subscription();
  Subscription(const Subscription&) = delete;
  Subscription& operator=(const Subscription&) = delete;

  /// The next item, waiting up to `timeout`; nullptr on timeout or once the
  /// subscription is closed and drained.
  HubItemPtr Next(std::chrono::milliseconds timeout);
  /// Items dropped because the queue was full, since subscribing.
  std::uint64_t dropped() const;
  /// True once closed (by Close or the hub's Close): Next drains what is
  /// queued, then returns nullptr at once.
  bool closed() const;
  /// Stops delivery and wakes a waiting Next.
  void Close();

 private:
  friend class SampleHub;
  friend struct detail::HubCore;
  struct Queue;
  Subscription(std::shared_ptr<Queue> queue, std::shared_ptr<detail::HubCore> core);

  std::shared_ptr<Queue> queue_;
  std::shared_ptr<detail::HubCore> core_;
};

/// The hub. Publish* are called by the run service (on the run's thread for
/// samples and progress: they copy the item once and return).
class SampleHub {
 public:
  SampleHub();
  /// Closes every subscription (their Next returns nullptr).
  ~SampleHub();
  SampleHub(const SampleHub&) = delete;
  SampleHub& operator=(const SampleHub&) = delete;

  /// A new subscription. Its first item is a kState item with the current
  /// state: the current (or last) run's id, state, reason and last progress
  /// (run_id 0 and kQueued before any run). With a run_id filter it is sent
  /// only if that run is the current (or last) one; otherwise the caller
  /// reports the run's stored state itself.
  std::unique_ptr<Subscription> Subscribe(SubscribeOptions options = {});

  /// Publishes `item` (its seq is assigned here) to every subscriber whose
  /// filter matches, and records kState/kProgress/kEnd as the current state.
  /// Returns the seq.
  std::uint64_t Publish(HubItem item);

  /// Closes every subscription and refuses new ones (they start closed).
  void Close();
  std::size_t subscriber_count() const;
  /// Items dropped over all subscriptions so far.
  std::uint64_t total_dropped() const;

 private:
  std::shared_ptr<detail::HubCore> core_;
};

/// While it lives, every parameter set `db` stores (by a run, a job or an
/// import) is published on `hub` as a kParameterSet item once its
/// transaction has committed: the SSE and DDS subscribers learn of new sets
/// without polling storage. One per database (it is the database's listener).
class ParameterSetEvents {
 public:
  ParameterSetEvents(storage::Database& db, SampleHub& hub);
  ~ParameterSetEvents();  ///< removes the listener.
  ParameterSetEvents(const ParameterSetEvents&) = delete;
  ParameterSetEvents& operator=(const ParameterSetEvents&) = delete;

 private:
  storage::Database& db_;
};

}  // namespace fesbench::server::services
