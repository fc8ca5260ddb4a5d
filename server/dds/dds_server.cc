#include "server/dds/dds_server.h"

#include <unistd.h>

#include <chrono>
#include <iostream>
#include <sstream>

#include "api/dds/fesbench.h"
#include "api/parameter_set_json.h"
#include "storage/parameter_sets.h"
#include "storage/subjects.h"
#include "api/time_utc.h"

namespace fesbench::server::dds {

namespace wire = fesbench::dds;
namespace fdds = eprosima::fastdds::dds;
using eprosima::fastrtps::types::ReturnCode_t;

namespace {

wire::RunState ToWire(protocols::RunState state) {
  switch (state) {
    case protocols::RunState::kQueued:
      return wire::RUN_QUEUED;
    case protocols::RunState::kRunning:
      return wire::RUN_RUNNING;
    case protocols::RunState::kDone:
      return wire::RUN_DONE;
    case protocols::RunState::kFailed:
      return wire::RUN_FAILED;
    case protocols::RunState::kAborted:
      return wire::RUN_ABORTED;
  }
  return wire::RUN_QUEUED;
}

wire::Channel MakeChannel(const char* name, const char* unit, const std::vector<double>& values) {
  wire::Channel c;
  c.name(name);
  c.unit(unit);
  c.values(values);
  return c;
}

std::string HostName() {
  char name[256] = {};
  if (::gethostname(name, sizeof(name) - 1) != 0 || name[0] == '\0') return "fesbench";
  return name;
}

}  // namespace

DdsServer::DdsServer(const DdsServerOptions& options, storage::Database& db,
                     services::RunService& runs, services::SampleHub& hub,
                     services::CommandService& commands)
    : options_(options), db_(db), runs_(runs), hub_(hub), commands_(commands) {
  if (options_.bench_id.empty()) options_.bench_id = HostName();
}

api::Result<std::unique_ptr<DdsServer>> DdsServer::Start(const DdsServerOptions& options,
                                                         storage::Database& db,
                                                         services::RunService& runs,
                                                         services::SampleHub& hub,
                                                         services::CommandService& commands) {
  std::unique_ptr<DdsServer> server(new DdsServer(options, db, runs, hub, commands));
  if (api::Status st = server->Init(); !st.ok()) return st;
  return server;
}

api::Status DdsServer::Init() {
  auto participant = wire::Participant::Create(options_.participant);
  if (!participant.ok()) return participant.status();
  participant_ = std::move(*participant);
  auto& p = *participant_;
  samples_ = p.MakeWriter(p.samples());
  state_ = p.MakeWriter(p.bench_state());
  events_ = p.MakeWriter(p.run_events());
  parameter_sets_ = p.MakeWriter(p.parameter_sets());
  replies_ = p.MakeWriter(p.replies());
  commands_reader_ = p.MakeReader(p.commands());
  if (!samples_ || !state_ || !events_ || !parameter_sets_ || !replies_ || !commands_reader_) {
    if (p.secured()) {
      return api::Status::InvalidArgument(
          "the DDS identity's permissions do not grant the server's topics (publish samples, "
          "state, run events, parameter sets and replies; subscribe commands): give the server "
          "an identity of role 'server' (scripts/make-dds-pki.sh)",
          "dds-identity");
    }
    return api::Status::Unavailable("Fast DDS could not create the fesbench writers/readers");
  }
  services::SubscribeOptions sub;
  sub.capacity = options_.hub_capacity;
  subscription_ = hub_.Subscribe(sub);
  // The first items: the latest set of every leg and the bench state, before
  // any client can ask (transient local keeps them for late joiners).
  PublishLatestParameterSets();
  PublishStateIfChanged(true);
  forward_thread_ = std::thread([this] { ForwardLoop(); });
  housekeeping_thread_ = std::thread([this] { HousekeepingLoop(); });
  command_thread_ = std::thread([this] { CommandLoop(); });
  return api::Status::Ok();
}

DdsServer::~DdsServer() { Stop(); }

void DdsServer::Stop() {
  if (stop_.exchange(true)) return;
  if (subscription_) subscription_->Close();
  Wake();
  for (std::thread* t : {&forward_thread_, &housekeeping_thread_, &command_thread_}) {
    if (t->joinable()) t->join();
  }
  subscription_.reset();
  participant_.reset();
}

DdsServerStats DdsServer::stats() const {
  std::lock_guard lock(stats_mu_);
  DdsServerStats s = stats_;
  return s;
}

void DdsServer::Wake() {
  {
    std::lock_guard lock(wake_mu_);
    wake_ = true;
  }
  wake_cv_.notify_all();
}

// --- hub items: sample blocks and run events ------------------------------------------------

void DdsServer::ForwardLoop() {
  using namespace std::chrono_literals;
  while (!stop_.load()) {
    services::HubItemPtr item = subscription_->Next(200ms);
    if (!item) {
      if (subscription_->closed()) return;
      continue;
    }
    try {
      PublishItem(*item);
    } catch (const std::exception& e) {
      std::cerr << "fesbench-server: DDS publish: " << e.what() << std::endl;
    }
  }
}

void DdsServer::PublishItem(const services::HubItem& item) {
  using Kind = services::HubItem::Kind;
  if (item.kind == Kind::kSamples) {
    if (item.run_id != block_run_id_) {
      block_run_id_ = item.run_id;
      block_seq_ = 0;
    }
    const protocols::SampleBatch& b = item.samples;
    wire::SampleBlock block;
    block.bench_id(options_.bench_id);
    block.run_id(item.run_id);
    block.block_seq(++block_seq_);
    block.first_sample(item.first_sample);
    block.trial(b.trial);
    block.trial_name(b.trial_name);
    block.t_s(b.t_s);
    block.channels().push_back(MakeChannel("stim", "mA", b.stim_ma));
    block.channels().push_back(MakeChannel("angle", "deg", b.angle_deg));
    block.channels().push_back(MakeChannel("torque", "N.m", b.torque_nm));
    block.channels().push_back(MakeChannel("accel", "m/s2", b.accel_m_s2));
    // Tracking runs: the target and the adaptive controller's τ̂_scale.
    if (!b.target_deg.empty()) block.channels().push_back(MakeChannel("target", "deg", b.target_deg));
    if (!b.tau_scale_nm.empty()) {
      block.channels().push_back(MakeChannel("tau_scale", "N.m", b.tau_scale_nm));
    }
    block.published_ns(wire::NowNs());
    block.published_mono_ns(wire::MonotonicNs());
    samples_->write(&block);
    std::lock_guard lock(stats_mu_);
    ++stats_.sample_blocks;
    stats_.hub_dropped = subscription_->dropped();
    return;
  }
  if (item.kind == Kind::kProgress) {
    Wake();  // the bench state carries the progress
    return;
  }
  if (item.kind == Kind::kParameterSet) {
    auto set = storage::ParameterSetRepository(db_).Get(item.parameter_set_id.value_or(0));
    if (set.ok()) {
      PublishParameterSet(*set);
    } else {
      std::cerr << "fesbench-server: DDS parameter set: " << set.status().ToString() << std::endl;
    }
    return;
  }
  if (item.run_id == 0) return;  // the initial state before any run
  wire::RunEvent event;
  event.bench_id(options_.bench_id);
  event.run_id(item.run_id);
  event.state(ToWire(item.state));
  event.reason(item.reason);
  event.trial_id(item.trial_id.value_or(0));
  event.parameter_set_id(item.parameter_set_id.value_or(0));
  event.end(item.kind == Kind::kEnd);
  event.stamp_ns(wire::NowNs());
  if (item.kind == Kind::kTrial) {
    auto view = runs_.Get(item.run_id);
    if (view.ok()) event.state(ToWire(view->state));
  }
  events_->write(&event);
  {
    std::lock_guard lock(stats_mu_);
    ++stats_.run_events;
  }
  Wake();
}

// --- bench state and parameter sets ----------------------------------------------------------

void DdsServer::HousekeepingLoop() {
  const auto check = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(options_.state_check_s));
  while (!stop_.load()) {
    {
      std::unique_lock lock(wake_mu_);
      wake_cv_.wait_for(lock, check, [this] { return wake_ || stop_.load(); });
      wake_ = false;
    }
    if (stop_.load()) return;
    try {
      PublishStateIfChanged(false);
    } catch (const std::exception& e) {
      std::cerr << "fesbench-server: DDS housekeeping: " << e.what() << std::endl;
    }
  }
}

void DdsServer::PublishStateIfChanged(bool force) {
  const services::BenchState s = runs_.State();
  wire::BenchState state;
  state.bench_id(options_.bench_id);
  state.kind(s.kind);
  state.mode(s.mode);
  state.busy(s.busy);
  state.estopped(s.estopped);
  state.estop_source(s.estop_source);
  state.owner(s.owner);
  state.run_id(s.run_id.value_or(0));
  state.protocol(s.protocol);
  state.run_state(ToWire(s.run_state));
  state.progress_fraction(s.progress.fraction);
  state.eta_s(s.progress.eta_s);
  std::ostringstream key;  // everything but the time stamp
  key << s.kind << '|' << s.mode << '|' << s.busy << '|' << s.estopped << '|' << s.estop_source
      << '|' << s.owner << '|' << state.run_id() << '|' << s.protocol << '|'
      << static_cast<int>(s.run_state) << '|' << s.progress.fraction;
  if (!force && key.str() == last_state_) return;
  last_state_ = key.str();
  state.updated_ns(wire::NowNs());
  state_->write(&state);
  std::lock_guard lock(stats_mu_);
  ++stats_.bench_states;
}

void DdsServer::PublishLatestParameterSets() {
  storage::SubjectRepository subjects(db_);
  storage::ParameterSetRepository sets(db_);
  auto all = subjects.List();
  if (!all.ok()) {
    std::cerr << "fesbench-server: DDS parameter sets: " << all.status().ToString() << std::endl;
    return;
  }
  for (const storage::Subject& subject : *all) {
    auto legs = subjects.Legs(subject.id);
    if (!legs.ok()) continue;
    for (const storage::Leg& leg : *legs) {
      // The set that gates stimulation, else the newest (kNotFound: no set yet).
      auto shown = sets.Approved(leg.id);
      if (!shown.ok()) shown = sets.Latest(subject.id, leg.id);
      if (shown.ok()) PublishParameterSet(*shown);
    }
  }
}

void DdsServer::PublishParameterSet(const storage::StoredParameterSet& set) {
  const storage::ParameterSetSummary& sum = set.summary;
  const auto key = std::make_pair(sum.subject_id, sum.leg_id);
  auto approval = storage::ParameterSetRepository(db_).LegApproval(sum.leg_id);
  if (!approval.ok()) {
    std::cerr << "fesbench-server: DDS parameter set " << sum.id << ": "
              << approval.status().ToString() << std::endl;
    return;
  }
  const std::int64_t approved_id = *approval ? (*approval)->parameter_set_id : 0;
  // Per leg (the topic is keyed by subject and leg): a newer version, or an
  // approval; never an older unapproved set over what was published.
  auto it = published_sets_.find(key);
  if (it != published_sets_.end()) {
    const auto [last_id, last_approved] = it->second;
    const bool newer = sum.id > last_id;
    const bool approval_changed = approved_id != last_approved && approved_id == sum.id;
    if (!newer && !approval_changed) return;
  }
  wire::ParameterSet msg;
  msg.subject_id(sum.subject_id);
  msg.leg_id(sum.leg_id);
  msg.parameter_set_id(sum.id);
  msg.version(sum.version);
  msg.model(sum.model);
  msg.irc_method(sum.irc_method);
  msg.passive_method(sum.passive_method);
  msg.active_method(sum.active_method);
  msg.created_at(api::FormatUtc(sum.created_at));
  msg.parameters_json(api::ParameterSetToJson(set.params).dump());
  msg.approved(approved_id == sum.id);
  msg.approved_parameter_set_id(approved_id);
  if (parameter_sets_->write(&msg)) {
    published_sets_[key] = {sum.id, approved_id};
    std::lock_guard lock(stats_mu_);
    ++stats_.parameter_sets;
  }
}

// --- commands ----------------------------------------------------------------------------

void DdsServer::CommandLoop() {
  const eprosima::fastrtps::Duration_t wait(0, 100000000);  // 100 ms
  while (!stop_.load()) {
    if (!commands_reader_->wait_for_unread_message(wait)) continue;
    wire::Command command;
    fdds::SampleInfo info;
    while (!stop_.load() &&
           commands_reader_->take_next_sample(&command, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      if (!command.bench_id().empty() && command.bench_id() != options_.bench_id) continue;
      wire::CommandReply reply;
      reply.request_id(command.request_id());
      reply.bench_id(options_.bench_id);
      reply.kind(command.kind());
      api::Status st = api::Status::Ok();
      try {
        switch (command.kind()) {
          case wire::CMD_ESTOP:
            st = commands_.EStop(command.token());
            break;
          case wire::CMD_START_RUN: {
            protocols::ParameterValues values;
            for (const auto& p : command.parameters()) values[p.name()] = p.value();
            auto view = commands_.StartRun(command.token(), command.session_id(),
                                           command.protocol(), values);
            st = view.status();
            if (view.ok()) reply.run_id(view->run_id);
            break;
          }
          case wire::CMD_CANCEL_RUN:
            st = commands_.CancelRun(command.token(), command.run_id());
            reply.run_id(command.run_id());
            break;
          case wire::CMD_HEARTBEAT:
            st = commands_.Heartbeat(command.token(), command.run_id());
            reply.run_id(command.run_id());
            break;
          default:
            st = api::Status::InvalidArgument("unknown command kind", "kind");
        }
      } catch (const std::exception& e) {
        std::cerr << "fesbench-server: DDS command: " << e.what() << std::endl;
        st = api::Status(api::ErrorCode::kInternal, "internal server error");
      }
      reply.accepted(st.ok());
      reply.code(st.ok() ? "ok" : std::string(api::ErrorCodeName(st.code())));
      reply.reason(st.ok() || st.field().empty() ? st.message() : st.field() + ": " + st.message());
      replies_->write(&reply);
      {
        std::lock_guard lock(stats_mu_);
        ++stats_.commands;
      }
      Wake();  // an e-stop or a start changes the bench state at once
    }
  }
}

}  // namespace fesbench::server::dds
