// SampleHub: every item in order to a reading subscriber, bounded
// drop-oldest queues for one that never reads (publishing never waits for
// it), run filters, the current state for late subscribers, and closing.
#include "server/services/sample_hub.h"

#include <gtest/gtest.h>

#include <thread>

namespace fesbench::server::services {
namespace {

using namespace std::chrono_literals;

HubItem Samples(std::int64_t run_id, std::uint64_t first, std::size_t n) {
  HubItem item;
  item.kind = HubItem::Kind::kSamples;
  item.run_id = run_id;
  item.first_sample = first;
  for (std::size_t i = 0; i < n; ++i) item.samples.t_s.push_back(static_cast<double>(first + i));
  return item;
}

HubItem State(std::int64_t run_id, protocols::RunState state) {
  HubItem item;
  item.kind = HubItem::Kind::kState;
  item.run_id = run_id;
  item.state = state;
  return item;
}

TEST(SampleHub, FirstItemIsTheCurrentStateThenEveryItemInOrder) {
  SampleHub hub;
  auto sub = hub.Subscribe();
  HubItemPtr first = sub->Next(0ms);
  ASSERT_NE(first, nullptr);
  EXPECT_EQ(first->kind, HubItem::Kind::kState);
  EXPECT_EQ(first->run_id, 0);
  EXPECT_EQ(first->state, protocols::RunState::kQueued);

  EXPECT_EQ(hub.Publish(State(7, protocols::RunState::kRunning)), 1u);
  for (std::uint64_t k = 0; k < 100; ++k) hub.Publish(Samples(7, 40 * k, 40));
  std::uint64_t last_seq = 0;
  std::uint64_t next_sample = 0;
  HubItemPtr state = sub->Next(0ms);
  ASSERT_NE(state, nullptr);
  EXPECT_EQ(state->seq, 1u);
  last_seq = state->seq;
  for (int k = 0; k < 100; ++k) {
    HubItemPtr item = sub->Next(0ms);
    ASSERT_NE(item, nullptr);
    EXPECT_EQ(item->seq, last_seq + 1);
    last_seq = item->seq;
    EXPECT_EQ(item->first_sample, next_sample);
    ASSERT_EQ(item->samples.t_s.size(), 40u);
    EXPECT_EQ(item->samples.t_s.front(), static_cast<double>(next_sample));
    next_sample += 40;
  }
  EXPECT_EQ(sub->Next(1ms), nullptr);  // nothing more: timeout
  EXPECT_EQ(sub->dropped(), 0u);
}

TEST(SampleHub, ASubscriberThatNeverReadsKeepsOnlyTheNewestAndCountsDrops) {
  SampleHub hub;
  SubscribeOptions small;
  small.capacity = 4;
  auto stuck = hub.Subscribe(small);  // holds the initial state item
  auto reader = hub.Subscribe();
  std::uint64_t received = 0;
  for (std::uint64_t k = 0; k < 10000; ++k) {
    hub.Publish(Samples(1, k, 1));
    if (k % 100 == 99) {
      while (HubItemPtr item = reader->Next(0ms)) received += item->kind == HubItem::Kind::kSamples;
    }
  }
  EXPECT_EQ(received, 10000u);
  EXPECT_EQ(reader->dropped(), 0u);
  // 1 initial state + 10000 items through a queue of 4: all but the last 4 dropped.
  EXPECT_EQ(stuck->dropped(), 10001u - 4u);
  EXPECT_EQ(hub.total_dropped(), 10001u - 4u);
  for (std::uint64_t k = 9996; k < 10000; ++k) {
    HubItemPtr item = stuck->Next(0ms);
    ASSERT_NE(item, nullptr);
    EXPECT_EQ(item->first_sample, k);
  }
  EXPECT_EQ(stuck->Next(0ms), nullptr);
}

TEST(SampleHub, RunFilterAndLateSubscribersSeeTheCurrentStateWithProgress) {
  SampleHub hub;
  hub.Publish(State(3, protocols::RunState::kRunning));
  HubItem progress;
  progress.kind = HubItem::Kind::kProgress;
  progress.run_id = 3;
  progress.progress.fraction = 0.25;
  progress.progress.eta_s = 12.0;
  hub.Publish(progress);

  SubscribeOptions only4;
  only4.run_id = 4;
  auto other = hub.Subscribe(only4);
  EXPECT_EQ(other->Next(0ms), nullptr);  // run 3's state is not run 4's

  auto late = hub.Subscribe();
  HubItemPtr first = late->Next(0ms);
  ASSERT_NE(first, nullptr);
  EXPECT_EQ(first->kind, HubItem::Kind::kState);
  EXPECT_EQ(first->run_id, 3);
  EXPECT_EQ(first->state, protocols::RunState::kRunning);
  EXPECT_DOUBLE_EQ(first->progress.fraction, 0.25);
  EXPECT_DOUBLE_EQ(first->progress.eta_s, 12.0);

  hub.Publish(Samples(3, 0, 5));
  hub.Publish(State(4, protocols::RunState::kRunning));
  hub.Publish(Samples(4, 0, 5));
  HubItemPtr a = other->Next(0ms);
  HubItemPtr b = other->Next(0ms);
  ASSERT_NE(a, nullptr);
  ASSERT_NE(b, nullptr);
  EXPECT_EQ(a->run_id, 4);
  EXPECT_EQ(a->kind, HubItem::Kind::kState);
  EXPECT_EQ(b->run_id, 4);
  EXPECT_EQ(b->kind, HubItem::Kind::kSamples);
  EXPECT_EQ(other->Next(0ms), nullptr);
}

TEST(SampleHub, CloseWakesAWaitingReaderAndUnsubscribeRemoves) {
  SampleHub hub;
  auto sub = hub.Subscribe();
  ASSERT_NE(sub->Next(0ms), nullptr);  // initial state
  EXPECT_EQ(hub.subscriber_count(), 1u);
  std::thread closer([&] {
    std::this_thread::sleep_for(20ms);
    hub.Close();
  });
  // Waits far longer than the close takes; returns nullptr once closed.
  EXPECT_EQ(sub->Next(60s), nullptr);
  closer.join();
  EXPECT_TRUE(sub->closed());
  auto after = hub.Subscribe();
  EXPECT_TRUE(after->closed());
  EXPECT_EQ(after->Next(0ms), nullptr);
  sub.reset();
  EXPECT_EQ(hub.subscriber_count(), 0u);
}

TEST(SampleHub, ASubscriptionMayOutliveTheHub) {
  auto hub = std::make_unique<SampleHub>();
  auto sub = hub->Subscribe();
  hub->Publish(State(1, protocols::RunState::kRunning));
  hub.reset();
  EXPECT_TRUE(sub->closed());
  // Queued items remain readable after close.
  ASSERT_NE(sub->Next(0ms), nullptr);
  ASSERT_NE(sub->Next(0ms), nullptr);
  EXPECT_EQ(sub->Next(0ms), nullptr);
}

TEST(SampleHub, ItemJsonCarriesKindSeqAndPayload) {
  HubItem item = Samples(9, 80, 2);
  item.seq = 5;
  const nlohmann::json j = api::RunEventToJson(item);
  EXPECT_EQ(j.at("kind"), "samples");
  EXPECT_EQ(j.at("seq"), 5);
  EXPECT_EQ(j.at("run_id"), 9);
  EXPECT_EQ(j.at("first_sample"), 80);
  EXPECT_EQ(j.at("samples").at("t_s").size(), 2u);
  HubItem end;
  end.kind = HubItem::Kind::kEnd;
  end.state = protocols::RunState::kDone;
  end.parameter_set_id = 12;
  const nlohmann::json e = api::RunEventToJson(end);
  EXPECT_EQ(e.at("kind"), "end");
  EXPECT_EQ(e.at("state"), "done");
  EXPECT_EQ(e.at("parameter_set_id"), 12);
}

}  // namespace
}  // namespace fesbench::server::services
