#include "clients/dds_monitor/monitor.h"

#include <unistd.h>

#include <chrono>
#include <iomanip>
#include <map>
#include <nlohmann/json.hpp>
#include <ostream>
#include <thread>

#include "api/dds/fesbench.h"

namespace fesbench::dds_monitor {

namespace fdds = eprosima::fastdds::dds;
using eprosima::fastrtps::types::ReturnCode_t;
using Clock = std::chrono::steady_clock;

namespace {

const eprosima::fastrtps::Duration_t kPoll(0, 50000000);  // 50 ms

Clock::time_point Deadline(double seconds) {
  return Clock::now() +
         std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

api::Status NoServer(const MonitorOptions& o) {
  std::ostringstream msg;
  msg << "no fesbench server found on DDS domain " << o.participant.domain_id << " (transport "
      << dds::TransportName(o.participant.transport) << ") within " << o.timeout_s << " s";
  return api::Status::Unavailable(msg.str());
}

template <class T>
std::vector<T> TakeAll(fdds::DataReader* reader) {
  std::vector<T> out;
  T value;
  fdds::SampleInfo info;
  while (reader->take_next_sample(&value, &info) == ReturnCode_t::RETCODE_OK) {
    if (info.valid_data) out.push_back(value);
  }
  return out;
}

bool Matched(fdds::DataReader* reader) {
  fdds::SubscriptionMatchedStatus status;
  reader->get_subscription_matched_status(status);
  return status.current_count > 0;
}

bool Matched(fdds::DataWriter* writer) {
  fdds::PublicationMatchedStatus status;
  writer->get_publication_matched_status(status);
  return status.current_count > 0;
}

api::Result<std::unique_ptr<dds::Participant>> Join(const MonitorOptions& options) {
  dds::ParticipantOptions p = options.participant;
  if (p.name.empty() || p.name == "fesbench") p.name = "fesbench-dds-monitor";
  return dds::Participant::Create(p);
}

const char* RunStateName(dds::RunState state) {
  switch (state) {
    case dds::RUN_QUEUED:
      return "queued";
    case dds::RUN_RUNNING:
      return "running";
    case dds::RUN_DONE:
      return "done";
    case dds::RUN_FAILED:
      return "failed";
    case dds::RUN_ABORTED:
      return "aborted";
  }
  return "?";
}

}  // namespace

api::Result<int> ListBenches(const MonitorOptions& options, std::ostream& out) {
  auto participant = Join(options);
  if (!participant.ok()) return participant.status();
  auto& p = **participant;
  fdds::DataReader* reader = p.MakeReader(p.bench_state());
  if (!reader) return api::Status::Unavailable("cannot create a DDS reader");
  std::map<std::string, dds::BenchState> benches;
  auto deadline = Deadline(options.timeout_s);
  bool settling = false;
  while (Clock::now() < deadline) {
    reader->wait_for_unread_message(kPoll);
    for (auto& s : TakeAll<dds::BenchState>(reader)) benches[s.bench_id()] = s;
    // Once one bench answered, give the others a moment (transient local: they answer at once).
    if (!benches.empty() && !settling) {
      settling = true;
      deadline = std::min(deadline, Deadline(0.5));
    }
  }
  if (benches.empty()) return NoServer(options);
  for (const auto& [id, s] : benches) {
    out << id << "  kind " << s.kind() << "  mode " << s.mode() << "  "
        << (s.estopped() ? "E-STOPPED (" + s.estop_source() + ")" : std::string("no e-stop"))
        << "  " << (s.busy() ? "busy" : "idle");
    if (!s.owner().empty()) out << "  owner " << s.owner();
    if (s.run_id() != 0) {
      out << "  run " << s.run_id() << " " << s.protocol() << " " << RunStateName(s.run_state())
          << " " << std::fixed << std::setprecision(0) << 100.0 * s.progress_fraction() << "%"
          << std::setprecision(1) << " eta " << s.eta_s() << " s" << std::defaultfloat;
    }
    out << "\n";
  }
  return static_cast<int>(benches.size());
}

api::Result<std::uint64_t> StreamSamples(const MonitorOptions& options, std::int64_t run_id,
                                         bool csv, std::uint64_t max_samples, std::ostream& out) {
  auto participant = Join(options);
  if (!participant.ok()) return participant.status();
  auto& p = **participant;
  fdds::DataReader* samples = p.MakeReader(p.samples());
  fdds::DataReader* events = p.MakeReader(p.run_events());
  if (!samples || !events) return api::Status::Unavailable("cannot create a DDS reader");
  auto deadline = Deadline(options.timeout_s);
  while (!Matched(samples)) {
    if (Clock::now() >= deadline) return NoServer(options);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  std::uint64_t count = 0;
  std::uint64_t last_block = 0;
  bool header = false;
  bool ended = false;
  deadline = Deadline(options.timeout_s);
  out << std::setprecision(10);
  while (!ended && (max_samples == 0 || count < max_samples)) {
    if (Clock::now() >= deadline) {
      return api::Status::Unavailable("no samples of run " + std::to_string(run_id) + " within " +
                                      std::to_string(options.timeout_s) + " s (is it running?)");
    }
    samples->wait_for_unread_message(kPoll);
    for (const auto& b : TakeAll<dds::SampleBlock>(samples)) {
      if (b.run_id() != run_id) continue;
      deadline = Deadline(options.timeout_s);
      if (last_block != 0 && b.block_seq() != last_block + 1) {
        return api::Status::DataLoss("sample blocks " + std::to_string(last_block + 1) + " to " +
                                     std::to_string(b.block_seq() - 1) + " of run " +
                                     std::to_string(run_id) + " were lost");
      }
      last_block = b.block_seq();
      if (!header) {
        header = true;
        out << (csv ? "run_id,trial,t_s" : "# run trial t_s");
        for (const auto& c : b.channels()) {
          out << (csv ? "," : " ") << c.name() << "_" << c.unit();
        }
        out << "\n";
      }
      for (std::size_t i = 0; i < b.t_s().size(); ++i) {
        if (max_samples != 0 && count >= max_samples) break;
        const char* sep = csv ? "," : " ";
        out << run_id << sep << b.trial() << sep << b.t_s()[i];
        for (const auto& c : b.channels())
          out << sep << (i < c.values().size() ? c.values()[i] : 0.0);
        out << "\n";
        ++count;
      }
    }
    for (const auto& e : TakeAll<dds::RunEvent>(events)) {
      if (e.run_id() == run_id && e.end()) ended = true;
    }
  }
  // Blocks published just before the end event.
  if (ended) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    for (const auto& b : TakeAll<dds::SampleBlock>(samples)) {
      if (b.run_id() != run_id) continue;
      for (std::size_t i = 0; i < b.t_s().size() && (max_samples == 0 || count < max_samples);
           ++i) {
        const char* sep = csv ? "," : " ";
        out << run_id << sep << b.trial() << sep << b.t_s()[i];
        for (const auto& c : b.channels())
          out << sep << (i < c.values().size() ? c.values()[i] : 0.0);
        out << "\n";
        ++count;
      }
    }
  }
  out.flush();
  return count;
}

api::Status ShowParameterSet(const MonitorOptions& options, std::int64_t subject_id,
                             std::int64_t leg_id, std::ostream& out) {
  auto participant = Join(options);
  if (!participant.ok()) return participant.status();
  auto& p = **participant;
  fdds::DataReader* reader = p.MakeReader(p.parameter_sets());
  if (!reader) return api::Status::Unavailable("cannot create a DDS reader");
  auto deadline = Deadline(options.timeout_s);
  bool matched = false;
  while (Clock::now() < deadline) {
    reader->wait_for_unread_message(kPoll);
    for (const auto& s : TakeAll<dds::ParameterSet>(reader)) {
      if (s.subject_id() != subject_id || s.leg_id() != leg_id) continue;
      out << "subject " << s.subject_id() << " leg " << s.leg_id() << ": parameter set "
          << s.parameter_set_id() << " version " << s.version() << ", model " << s.model()
          << ", created " << s.created_at() << "\n"
          << "methods: irc " << s.irc_method() << ", passive " << s.passive_method() << ", active "
          << s.active_method() << "\n"
          << (s.approved() ? std::string("approved: yes, the leg's approved set\n")
                           : s.approved_parameter_set_id() != 0
                               ? "approved: no (the leg's approved set is " +
                                     std::to_string(s.approved_parameter_set_id()) + ")\n"
                               : std::string("approved: no set of the leg is approved\n"));
      auto json = nlohmann::json::parse(s.parameters_json(), nullptr, false);
      out << (json.is_discarded() ? s.parameters_json() : json.dump(2)) << "\n";
      return api::Status::Ok();
    }
    // Transient local: once matched, the stored sets arrive at once.
    if (!matched && Matched(reader)) {
      matched = true;
      deadline = std::min(deadline, Deadline(1.0));
    }
  }
  if (!matched) return NoServer(options);
  return api::Status::NotFound("no parameter set for subject " + std::to_string(subject_id) +
                               " leg " + std::to_string(leg_id));
}

api::Status SendEStop(const MonitorOptions& options, const std::string& token,
                      const std::string& bench_id, std::ostream& out) {
  auto participant = Join(options);
  if (!participant.ok()) return participant.status();
  auto& p = **participant;
  fdds::DataWriter* writer = p.MakeWriter(p.commands());
  fdds::DataReader* replies = p.MakeReader(p.replies());
  if (!writer && p.secured()) {
    return api::Status(api::ErrorCode::kPermissionDenied,
                       "this DDS identity's permissions do not grant publishing fesbench/commands "
                       "(an e-stop needs an identity of role 'operator')");
  }
  if (!writer || !replies) return api::Status::Unavailable("cannot create a DDS writer/reader");
  auto deadline = Deadline(options.timeout_s);
  while (!Matched(writer) || !Matched(replies)) {
    if (Clock::now() >= deadline) return NoServer(options);
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  dds::Command command;
  command.request_id("dds-monitor-" + std::to_string(::getpid()) + "-" +
                     std::to_string(dds::NowNs()));
  command.token(token);
  command.bench_id(bench_id);
  command.kind(dds::CMD_ESTOP);
  writer->write(&command);
  deadline = Deadline(options.timeout_s);
  api::Status result = api::Status::Unavailable("no reply to the e-stop within " +
                                                std::to_string(options.timeout_s) + " s");
  bool any = false;
  // With bench_id "" every bench answers: collect replies until the timeout
  // once one came, or until the addressed bench answered.
  while (Clock::now() < deadline) {
    replies->wait_for_unread_message(kPoll);
    for (const auto& r : TakeAll<dds::CommandReply>(replies)) {
      if (r.request_id() != command.request_id()) continue;
      out << r.bench_id() << ": " << (r.accepted() ? "e-stop latched" : "refused: " + r.code())
          << (r.reason().empty() ? "" : " (" + r.reason() + ")") << "\n";
      const api::Status reply =
          r.accepted() ? api::Status::Ok()
                       : api::Status(api::ParseErrorCode(r.code()).value_or(api::ErrorCode::kInternal),
                                     r.reason());
      if (!any || !reply.ok()) result = reply;
      any = true;
      if (!bench_id.empty()) return result;
      deadline = std::min(deadline, Deadline(0.5));
    }
  }
  return result;
}

}  // namespace fesbench::dds_monitor
