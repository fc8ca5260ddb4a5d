// DDS sample-block latency and sustained rate between two processes on one
// host (docs/API.md, "DDS"; targets: p99 < 1 ms, 1 kHz with no loss).
//
// The program re-executes itself as an echo process (--dds-echo DOMAIN
// TRANSPORT) that reads fesbench/bench/samples with the server's QoS and
// answers on fesbench/bench/samples_echo. Latency is one way: the echo
// stamps the block with its CLOCK_MONOTONIC receive time (one clock per
// host), minus the publisher's published_mono_ns. Sustained rate: the
// publisher paces 1-sample blocks (the worst case: one message per sample)
// for 1 s at a given rate, then asks the echo how many arrived.
//
//   build-dds/benchmarks/dds_latency_bench [--benchmark_filter=...]
#include <benchmark/benchmark.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "api/dds/fesbench.h"
#include "api/dds/participant.h"

extern char** environ;

namespace {

namespace wire = fesbench::dds;
namespace fdds = eprosima::fastdds::dds;
using eprosima::fastrtps::types::ReturnCode_t;
using namespace std::chrono_literals;

constexpr const char* kEchoTopic = "fesbench/bench/samples_echo";
constexpr long long kCountRequest = -1;  // trial field of a "how many did you get" block

fdds::Topic* EchoTopic(wire::Participant& p) {
  return p.participant()->create_topic(kEchoTopic, "fesbench::dds::SampleBlock",
                                       fdds::TOPIC_QOS_DEFAULT);
}

volatile std::sig_atomic_t echo_stop = 0;
void StopEcho(int) { echo_stop = 1; }

// The echo process (ends cleanly on SIGTERM so no shared-memory segment is
// left behind): answers every block at once with its receive time; for
// a count request, answers with the number of blocks of that run received.
int EchoMain(int domain, const std::string& transport) {
  std::signal(SIGTERM, StopEcho);
  wire::ParticipantOptions o;
  o.domain_id = domain;
  o.transport = *wire::ParseTransport(transport);
  o.name = "dds-latency-echo";
  auto p = wire::Participant::Create(o);
  if (!p.ok()) return 1;
  fdds::DataReader* reader = (*p)->MakeReader((*p)->samples());
  fdds::DataWriterQos echo_qos = wire::WriterQosFor(wire::kRunEventsTopic);  // reliable
  fdds::DataWriter* writer = (*p)->publisher()->create_datawriter(EchoTopic(**p), echo_qos);
  std::map<long long, unsigned long long> received;
  const auto parent = ::getppid();
  wire::SampleBlock block;
  fdds::SampleInfo info;
  while (!echo_stop && ::getppid() == parent) {
    if (!reader->wait_for_unread_message({0, 100000000})) continue;
    while (reader->take_next_sample(&block, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      const long long now = wire::MonotonicNs();
      if (block.trial() == kCountRequest) {
        block.first_sample(received[block.run_id()]);
        block.published_ns(now);
        writer->write(&block);
      } else if (block.block_seq() == 0) {  // latency probe
        block.published_ns(now);
        writer->write(&block);
      } else {
        ++received[block.run_id()];
      }
    }
  }
  return 0;
}

wire::SampleBlock MakeBlock(std::size_t samples) {
  wire::SampleBlock b;
  b.bench_id("bench");
  std::vector<double> t(samples), v(samples, 1.0);
  for (std::size_t i = 0; i < samples; ++i) t[i] = static_cast<double>(i) / 200.0;
  b.t_s(t);
  for (const char* name : {"stim", "angle", "torque", "accel"}) {
    wire::Channel c;
    c.name(name);
    c.unit("u");
    c.values(v);
    b.channels().push_back(c);
  }
  return b;
}

struct EchoProcess {
  EchoProcess(int domain, const char* transport) {
    const std::string d = std::to_string(domain);
    char* argv[] = {const_cast<char*>("/proc/self/exe"), const_cast<char*>("--dds-echo"),
                    const_cast<char*>(d.c_str()), const_cast<char*>(transport), nullptr};
    if (posix_spawn(&pid, "/proc/self/exe", nullptr, nullptr, argv, environ) != 0) pid = -1;
  }
  ~EchoProcess() {
    if (pid > 0) {
      ::kill(pid, SIGTERM);
      ::waitpid(pid, nullptr, 0);
    }
  }
  pid_t pid = -1;
};

struct Rig {
  Rig(int domain, const char* transport) : echo(domain, transport) {
    wire::ParticipantOptions o;
    o.domain_id = domain;
    o.transport = *wire::ParseTransport(transport);
    o.name = "dds-latency-publisher";
    auto created = wire::Participant::Create(o);
    if (!created.ok()) return;
    p = std::move(*created);
    writer = p->MakeWriter(p->samples());
    reader = p->subscriber()->create_datareader(EchoTopic(*p),
                                                wire::ReaderQosFor(wire::kRunEventsTopic));
    const auto until = std::chrono::steady_clock::now() + 20s;
    fdds::PublicationMatchedStatus pub;
    fdds::SubscriptionMatchedStatus sub;
    while (std::chrono::steady_clock::now() < until) {
      writer->get_publication_matched_status(pub);
      reader->get_subscription_matched_status(sub);
      if (pub.current_count > 0 && sub.current_count > 0) break;
      std::this_thread::sleep_for(10ms);
    }
    // Matched here does not yet mean matched in the echo process: probe
    // until a block makes the round trip, so no measurement starts early.
    wire::SampleBlock probe = MakeBlock(1), echo;
    probe.block_seq(0);
    for (int attempt = 0; attempt < 100 && !ready; ++attempt) {
      probe.run_id(-1 - attempt);
      writer->write(&probe);
      ready = Echo(probe.run_id(), echo, std::chrono::milliseconds(100));
    }
  }
  // The next echo of `run_id` (waiting up to `timeout`); false on timeout.
  bool Echo(long long run_id, wire::SampleBlock& out,
            std::chrono::milliseconds timeout = std::chrono::milliseconds(2000)) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    fdds::SampleInfo info;
    while (std::chrono::steady_clock::now() < until) {
      reader->wait_for_unread_message({0, 10000000});
      while (reader->take_next_sample(&out, &info) == ReturnCode_t::RETCODE_OK) {
        if (info.valid_data && out.run_id() == run_id) return true;
      }
    }
    return false;
  }
  EchoProcess echo;
  std::unique_ptr<wire::Participant> p;
  fdds::DataWriter* writer = nullptr;
  fdds::DataReader* reader = nullptr;
  bool ready = false;
};

int DomainFor(int offset) { return 100 + static_cast<int>(::getpid() % 60) * 2 + offset; }

const char* TransportArg(int index) {
  static const char* names[] = {"shm", "udp-loopback"};
  return names[index];
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

// One-way publish-to-receive latency of a block (arg 0: transport; arg 1: samples per block).
void BM_DdsBlockLatency(benchmark::State& state) {
  Rig rig(DomainFor(0), TransportArg(static_cast<int>(state.range(0))));
  if (!rig.ready) {
    state.SkipWithError("echo process not matched");
    return;
  }
  wire::SampleBlock block = MakeBlock(static_cast<std::size_t>(state.range(1)));
  block.block_seq(0);
  std::vector<double> latencies_us;
  long long run_id = 0;
  int lost = 0;
  wire::SampleBlock echo;
  for (auto _ : state) {
    bool echoed = false;
    for (int attempt = 0; attempt < 5 && !echoed; ++attempt) {  // best effort: a probe may be lost
      block.run_id(++run_id);
      block.published_mono_ns(wire::MonotonicNs());
      rig.writer->write(&block);
      echoed = rig.Echo(run_id, echo, std::chrono::milliseconds(200));
      if (!echoed) ++lost;
    }
    if (!echoed) {
      state.SkipWithError("echo process not answering");
      return;
    }
    const double one_way_s =
        static_cast<double>(echo.published_ns() - block.published_mono_ns()) * 1e-9;
    state.SetIterationTime(one_way_s);
    latencies_us.push_back(one_way_s * 1e6);
  }
  state.counters["p50_us"] = Percentile(latencies_us, 0.50);
  state.counters["p99_us"] = Percentile(latencies_us, 0.99);
  state.counters["max_us"] = Percentile(latencies_us, 1.0);
  state.counters["probes_lost"] = lost;
  state.SetLabel(TransportArg(static_cast<int>(state.range(0))));
}
BENCHMARK(BM_DdsBlockLatency)
    ->ArgsProduct({{0, 1}, {1, 40}})
    ->UseManualTime()
    ->Iterations(2000)
    ->Unit(benchmark::kMicrosecond);

// 1-sample blocks paced at arg 1 samples/s for 1 s; counts what the echo received.
void BM_DdsSustainedRate(benchmark::State& state) {
  Rig rig(DomainFor(1), TransportArg(static_cast<int>(state.range(0))));
  if (!rig.ready) {
    state.SkipWithError("echo process not matched");
    return;
  }
  const double rate_hz = static_cast<double>(state.range(1));
  wire::SampleBlock block = MakeBlock(1);
  long long run_id = 1000;
  std::uint64_t sent_total = 0, received_total = 0;
  for (auto _ : state) {
    block.run_id(++run_id);
    block.trial(0);
    const auto start = std::chrono::steady_clock::now();
    const auto period = std::chrono::duration<double>(1.0 / rate_hz);
    std::uint64_t sent = 0;
    while (std::chrono::steady_clock::now() - start < 1s) {
      block.block_seq(++sent);
      block.published_mono_ns(wire::MonotonicNs());
      rig.writer->write(&block);
      std::this_thread::sleep_until(start +
                                    std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                        period * static_cast<double>(sent)));
    }
    std::this_thread::sleep_for(200ms);  // let the last blocks land
    wire::SampleBlock ask = MakeBlock(0);
    ask.run_id(run_id);
    ask.trial(kCountRequest);
    wire::SampleBlock answer;
    bool answered = false;
    for (int attempt = 0; attempt < 5 && !answered; ++attempt) {  // best effort: ask again
      rig.writer->write(&ask);
      answered = rig.Echo(run_id, answer);
    }
    if (!answered) {
      state.SkipWithError("count request unanswered");
      return;
    }
    sent_total += sent;
    received_total += answer.first_sample();
  }
  state.counters["sent"] = static_cast<double>(sent_total);
  state.counters["lost"] = static_cast<double>(sent_total - std::min(sent_total, received_total));
  state.counters["loss_pct"] =
      sent_total ? 100.0 * static_cast<double>(sent_total - std::min(sent_total, received_total)) /
                       static_cast<double>(sent_total)
                 : 0.0;
  state.SetLabel(TransportArg(static_cast<int>(state.range(0))));
}
BENCHMARK(BM_DdsSustainedRate)
    ->ArgsProduct({{0, 1}, {1000, 5000, 20000, 50000, 100000, 200000}})
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) {
  if (argc == 4 && std::strcmp(argv[1], "--dds-echo") == 0) {
    return EchoMain(std::atoi(argv[2]), argv[3]);
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
