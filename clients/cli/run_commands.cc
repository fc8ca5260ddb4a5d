// `fesbench run start|show|stop|cancel` and `fesbench estop`: protocol runs on the
// bench (docs/PROTOCOLS.md, docs/SAFETY.md, docs/API.md). `run start` follows the run's event
// stream to its end while heart-beating it, because the server's watchdog
// stops a run whose controlling user goes silent for more than a second;
// Ctrl-C cancels the run and exits 130 once the server confirms. `--detach`
// is refused for any protocol the watchdog would abort a second later.
// A tolerance test followed on a terminal stops at the amplitude reached when
// the clinician presses Enter (`run stop` does the same from elsewhere).

#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <ostream>
#include <string>
#include <thread>
#include <vector>

#include "api/json_fields.h"
#include "api/protocol_info.h"
#include "api/run.h"
#include "api/run_start.h"
#include "api/trial.h"
#include "api/trial_import.h"
#include "clients/cli/commands.h"
#include "clients/cli/config.h"
#include "clients/cli/output.h"

namespace fesbench::cli {

namespace {

using nlohmann::json;

constexpr auto kHeartbeatPeriod = std::chrono::milliseconds(250);
constexpr int kBarWidth = 30;

std::string FormatEta(double eta_s) {
  if (!std::isfinite(eta_s)) return "--";
  const double s = std::max(0.0, eta_s);
  char buffer[32];
  if (s >= 60.0) {
    std::snprintf(buffer, sizeof buffer, "%dm%02ds", static_cast<int>(s) / 60,
                  static_cast<int>(s) % 60);
  } else {
    std::snprintf(buffer, sizeof buffer, "%.0fs", s);
  }
  return buffer;
}

// Renders progress events: a redrawn bar on a terminal, or one plain line
// per 5 % of progress (and per state or trial) when piped.
class ProgressPrinter {
 public:
  ProgressPrinter(std::ostream& out, bool terminal) : out_(out), terminal_(terminal) {}

  void Progress(const api::Progress& progress) {
    const double fraction = std::clamp(progress.fraction, 0.0, 1.0);
    const int percent = static_cast<int>(std::floor(fraction * 100.0));
    const std::string phase(api::StepPhaseName(progress.phase));
    const std::string eta = FormatEta(progress.eta_s);
    if (terminal_) {
      const int filled = static_cast<int>(std::round(fraction * kBarWidth));
      out_ << "\r[" << std::string(static_cast<std::size_t>(filled), '#')
           << std::string(static_cast<std::size_t>(kBarWidth - filled), '.') << "] ";
      char pct[8];
      std::snprintf(pct, sizeof pct, "%3d%%", percent);
      out_ << pct << "  ETA " << eta << "  " << phase << "        " << std::flush;
      bar_shown_ = true;
      return;
    }
    if (percent / 5 == last_bucket_) return;
    last_bucket_ = percent / 5;
    out_ << "progress " << percent << "% eta " << eta << " step " << progress.step
         << " " << phase << "\n"
         << std::flush;
  }

  void Line(const std::string& text) {
    if (bar_shown_) {
      out_ << "\n";
      bar_shown_ = false;
    }
    out_ << text << "\n" << std::flush;
  }

 private:
  std::ostream& out_;
  bool terminal_;
  bool bar_shown_ = false;
  int last_bucket_ = -1;
};

// Sends POST /runs/{id}/heartbeat every kHeartbeatPeriod until destroyed.
class Heartbeat {
 public:
  Heartbeat(const CliConfig& connection, std::int64_t run_id)
      : thread_([this, connection, run_id] {
          ApiClient client(connection);
          const std::string path = "/runs/" + std::to_string(run_id) + "/heartbeat";
          std::unique_lock lock(mu_);
          while (!stop_) {
            lock.unlock();
            try {
              client.Post(path);
            } catch (const CliError&) {
              // The run may have ended meanwhile; the stream reports that.
            }
            lock.lock();
            cv_.wait_for(lock, kHeartbeatPeriod, [this] { return stop_; });
          }
        }) {}
  ~Heartbeat() {
    {
      std::lock_guard lock(mu_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  bool stop_ = false;
  std::thread thread_;
};

// While alive, Enter on a terminal's standard input asks the server to stop
// the run "here" (POST /runs/{id}/stop: a tolerance test records the amplitude
// reached as the max tolerated, Appendix F part II.K). Polls, so that it ends
// with the run; end of input only stops the listening.
class StopKey {
 public:
  StopKey(const CliConfig& connection, std::int64_t run_id, std::ostream& out)
      : thread_([this, connection, run_id, &out] {
          char buffer[256];
          while (!done_) {
            pollfd fd{STDIN_FILENO, POLLIN, 0};
            if (::poll(&fd, 1, 100) <= 0) continue;
            const ssize_t n = ::read(STDIN_FILENO, buffer, sizeof buffer);
            if (n <= 0) return;  // end of input: nobody can press Enter
            if (std::string_view(buffer, static_cast<std::size_t>(n)).find('\n') ==
                std::string_view::npos) {
              continue;
            }
            try {
              ApiClient(connection).Post("/runs/" + std::to_string(run_id) + "/stop");
              out << "\nstop requested: the amplitude reached is recorded\n" << std::flush;
            } catch (const CliError& e) {
              out << "\nstop: " << e.what() << "\n" << std::flush;
            }
            return;
          }
        }) {}
  ~StopKey() {
    done_ = true;
    thread_.join();
  }
  StopKey(const StopKey&) = delete;
  StopKey& operator=(const StopKey&) = delete;

 private:
  std::atomic<bool> done_ = false;
  std::thread thread_;
};

// Ctrl-C while following a run: the handler only raises this flag; the
// stream loop cancels the run and waits for the server to confirm its end.
volatile std::sig_atomic_t g_interrupted = 0;
extern "C" void OnInterrupt(int) { g_interrupted = 1; }

// Installs OnInterrupt for SIGINT while alive (the previous handler after).
class InterruptGuard {
 public:
  InterruptGuard() {
    g_interrupted = 0;
    previous_ = std::signal(SIGINT, OnInterrupt);
  }
  ~InterruptGuard() { std::signal(SIGINT, previous_ == SIG_ERR ? SIG_DFL : previous_); }
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;

 private:
  void (*previous_)(int) = SIG_DFL;
};

// One line of `run start --json` on standard output: {"event": E, "run_id":
// N, "data": the stream event's data}, flushed at once so that a reading
// script sees each event as it happens.
void JsonLine(CliContext& context, const std::string& event, std::int64_t run_id,
              const json& data) {
  context.out << nlohmann::ordered_json{{"event", event}, {"run_id", run_id}, {"data", data}}.dump()
              << "\n"
              << std::flush;
}

// Follows a run's stream to its end; throws CliError unless it ends "done"
// (exit 130 when Ctrl-C cancelled it). Progress goes to `progress_out` as
// text, or, with --json, every stream event to standard output as a JSON
// line (JsonLine) and only notes to `progress_out`.
// `stop_key`: Enter on a terminal stops the run where it is (StopKey).
void FollowRun(CliContext& context, ApiClient& client, const CliConfig& connection,
               std::int64_t run_id, std::ostream& progress_out, bool stop_key) {
  const bool json_lines = context.options.json;
  InterruptGuard interrupt_guard;
  Heartbeat heartbeat(connection, run_id);
  std::optional<StopKey> stopper;
  if (stop_key && ::isatty(STDIN_FILENO)) {
    progress_out << "press Enter to stop here and record the amplitude reached as the max "
                    "tolerated; Ctrl-C cancels without recording\n"
                 << std::flush;
    stopper.emplace(connection, run_id, progress_out);
  }
  ProgressPrinter printer(progress_out, context.out_is_terminal && &progress_out == &context.out);
  std::optional<api::RunEvent> end;
  std::optional<api::RunState> last_state;
  bool cancel_sent = false;
  client.Stream("/runs/" + std::to_string(run_id) + "/stream",
                [&](const std::string& event, const json& data) {
                  if (g_interrupted && !cancel_sent) {
                    cancel_sent = true;
                    printer.Line("interrupted: cancelling run " + std::to_string(run_id) + " …");
                    try {
                      ApiClient(connection).Post("/runs/" + std::to_string(run_id) + "/cancel");
                    } catch (const CliError& e) {
                      // Already over: the stream's end says how it ended.
                      printer.Line(std::string("cancel: ") + e.what());
                    }
                  }
                  if (json_lines) JsonLine(context, event, run_id, data);
                  api::Result<api::RunEvent> parsed = api::RunEventFromJson(data);
                  if (!parsed.ok()) {
                    printer.Line("note: unreadable " + event +
                                 " event: " + parsed.status().ToString());
                    return true;
                  }
                  if (parsed->kind == api::RunEvent::Kind::kEnd) {
                    end = *std::move(parsed);
                    return false;
                  }
                  if (json_lines) return true;
                  const api::RunEvent& e = *parsed;
                  switch (e.kind) {
                    case api::RunEvent::Kind::kState:
                      if (e.state != last_state) {
                        last_state = e.state;
                        printer.Line("state " + std::string(api::RunStateName(e.state)));
                      }
                      printer.Progress(e.progress);
                      break;
                    case api::RunEvent::Kind::kProgress:
                      printer.Progress(e.progress);
                      break;
                    case api::RunEvent::Kind::kTrial:
                      printer.Line("trial " + e.samples.trial_name + " stored as trial " +
                                   (e.trial_id ? std::to_string(*e.trial_id) : "-"));
                      break;
                    default:
                      break;
                  }
                  return true;
                });
  if (!end) {
    throw CliError::Unreachable("the event stream of run " + std::to_string(run_id) +
                                " closed before the run ended");
  }
  const std::string state(api::RunStateName(end->state));
  const json answer = client.Get("/runs/" + std::to_string(run_id));
  if (json_lines) JsonLine(context, "run", run_id, answer);
  const api::RunView ended = FromServer(api::RunViewFromJson(answer), "run");
  std::string line = "end " + state;
  if (end->parameter_set_id) line += " parameter_set " + std::to_string(*end->parameter_set_id);
  if (ended.outcome && ended.outcome->tolerance && end->state == api::RunState::kDone) {
    const api::ToleranceOutcome& tolerance = *ended.outcome->tolerance;
    line += " threshold_ma " + Cell(api::OrNull(tolerance.threshold_ma)) + " max_tolerated_ma " +
            Cell(api::OrNull(tolerance.max_tolerated_ma)) + " session_revision " +
            Cell(api::OrNull(ended.outcome->session_revision));
    if (tolerance.subject_signalled_limit.value_or(false)) {
      line += " (the subject signalled the limit)";
    }
    if (tolerance.ended_at_ceiling) {
      line += " (no max tolerated recorded: " + tolerance.message + ")";
    }
  }
  if (!json_lines) printer.Line(line);
  if (cancel_sent) {
    throw CliError(kExitInterrupted, "run " + std::to_string(run_id) + " cancelled (Ctrl-C): " +
                                         state + " " + end->reason);
  }
  if (end->state != api::RunState::kDone) {
    const std::string& reason = end->reason;
    throw CliError::Server("server: run " + std::to_string(run_id) + " ended " + state +
                           (reason.empty() ? "" : ": " + reason));
  }
}

void PrintRun(CliContext& context, const json& run) {
  if (context.options.json) {
    context.out << run.dump(2) << "\n";
    return;
  }
  json brief = run;
  brief.erase("values");
  PrintObject(context.out, brief);
}

// A target trajectory file: CSV with the columns t_s and angle_deg (any
// order, others ignored).
api::TargetSamples TargetSamplesFromCsv(const std::string& path) {
  const api::Result<std::string> text = api::ReadTextFile(path);
  if (!text.ok()) throw CliError::Usage("--target-csv: " + text.status().ToString());
  const api::Result<api::TextTable> table = api::ReadTextTable(*text, "csv");
  if (!table.ok()) throw CliError::Usage("--target-csv " + path + ": " + table.status().message());
  api::TargetSamples out;
  for (const char* name : {"t_s", "angle_deg"}) {
    const auto it = std::find(table->labels.begin(), table->labels.end(), name);
    if (it == table->labels.end()) {
      throw CliError::Usage("--target-csv " + path + ": no column " + name +
                            " (the file needs t_s and angle_deg)");
    }
    (std::string(name) == "t_s" ? out.t_s : out.angle_deg) =
        table->columns[static_cast<std::size_t>(it - table->labels.begin())];
  }
  return out;
}

struct StartForm {
  std::string session;
  std::string protocol;
  std::vector<std::string> params;
  std::string ceiling_reason;  // a tolerance test above the recorded max: why
  std::string target_csv;      // tracking: an uploaded target trajectory
  bool follow = false;         // the default; kept so that older scripts still work
  bool detach = false;
};

// Why a run of `protocol` (GET /protocols/{name}) cannot be left alone, or
// "" if it can: the watchdog aborts every run whose controller stops
// heart-beating, and it is there for stimulation and the motor.
std::string DetachRefusal(const json& sent) {
  const api::ProtocolInfo protocol = FromServer(api::ProtocolInfoFromJson(sent), "protocol");
  const std::string& name = protocol.name;
  std::string what;
  if (protocol.stimulates) {
    what = "stimulates the subject";
  } else if (protocol.bench_mode != "decoupled") {
    what = "moves the brace with the motor";
  } else {
    return "";
  }
  return "--detach refused: " + name + " " + what +
         ", and the server's watchdog aborts such a run about a second after its controller "
         "stops heart-beating; run it without --detach (this command then follows it, "
         "heart-beating, and Ctrl-C cancels it cleanly)";
}

// True when `protocol` measures the max tolerated amplitude (GET
// /protocols/{name}, measures_max_tolerated): the subject's stop then records
// the amplitude reached. False if the description cannot be read: the run
// is followed without the stop key.
bool MeasuresMaxTolerated(ApiClient& client, const std::string& protocol) {
  try {
    const api::Result<api::ProtocolInfo> info =
        api::ProtocolInfoFromJson(client.Get("/protocols/" + protocol));
    return info.ok() && info->measures_max_tolerated;
  } catch (const CliError&) {
    return false;
  }
}

// `run VERB RUN`: POST /runs/{id}/VERB, then the run's state (after
// `lead`, closed by ")" when lead is not empty) or, with --json, its view.
void AddRunRequest(CLI::App& run, CliContext& context, const std::string& verb,
                   const std::string& description, const std::string& lead) {
  auto id = std::make_shared<std::string>();
  CLI::App* sub = run.add_subcommand(verb, description);
  sub->add_option("run", *id, "run id")->required();
  sub->callback([id, &context, verb, lead] {
    context.action = [id, &context, verb, lead] {
      const std::int64_t run_id = ParseId(*id, "run");
      auto client = Connect(context);
      const json reply = client->Post("/runs/" + std::to_string(run_id) + "/" + verb);
      if (context.options.json) {
        context.out << reply.dump(2) << "\n";
        return;
      }
      const api::RunView view = FromServer(api::RunViewFromJson(reply), "run");
      context.out << "run " << run_id << ": " << lead << api::RunStateName(view.state)
                  << (lead.empty() ? "" : ")") << "\n";
    };
  });
}

}  // namespace

void RegisterRunCommands(CLI::App& app, CliContext& context) {
  CLI::App* run = app.add_subcommand("run", "Protocol runs: start, show, stop, cancel.");
  run->require_subcommand(1);
  {
    auto form = std::make_shared<StartForm>();
    CLI::App* start = run->add_subcommand(
        "start",
        "Start a protocol for a session (clinician or admin) and follow it to its end "
        "(heart-beating; Ctrl-C cancels the run and exits 130).");
    start->add_option("session", form->session, "session id")->required();
    start->add_option("protocol", form->protocol, "protocol name, e.g. rapid_parameterisation")
        ->required();
    start->add_option("--param", form->params, "protocol parameter key=value (repeatable)");
    start->add_option("--ceiling-reason", form->ceiling_reason,
                      "tolerance_test only: why its ceiling_ma goes above the session's recorded "
                      "max tolerated amplitude (required then; audited)");
    start->add_option("--target-csv", form->target_csv,
                      "tracking: a target trajectory to follow, a CSV with the columns t_s "
                      "(seconds) and angle_deg (degrees); sets --param target=uploaded");
    start->add_flag("--follow", form->follow,
                    "follow the run to its end (the default; progress bar on a terminal, lines "
                    "when piped)");
    start->add_flag("--detach", form->detach,
                    "start and return at once (refused for protocols the watchdog guards: "
                    "stimulation or motor)");
    start->callback([form, &context] {
      context.action = [form, &context] {
        if (form->detach && form->follow) {
          throw CliError::Usage("--detach and --follow exclude each other");
        }
        const std::int64_t session = ParseId(form->session, "session");
        api::StartRunRequest request{.protocol = form->protocol};
        for (const auto& text : form->params) {
          const auto [key, value] = ParseRunParameter(text);
          if (value.is_string()) {
            request.choices[key] = value.get<std::string>();
          } else {
            request.parameters[key] = value.get<double>();
          }
        }
        const CliConfig connection = ResolveConnection(context.options);
        ApiClient client(connection);
        if (form->detach) {
          const std::string refusal = DetachRefusal(client.Get("/protocols/" + form->protocol));
          if (!refusal.empty()) throw CliError::Usage(refusal);
        }
        if (!form->ceiling_reason.empty()) request.ceiling_reason = form->ceiling_reason;
        if (!form->target_csv.empty()) {
          request.target = TargetSamplesFromCsv(form->target_csv);
          // typed-reads: not JSON (the request's own map of parameters)
          if (!request.parameters.contains("target")) request.choices.try_emplace("target", "uploaded");
        }
        const json started = client.Post("/sessions/" + std::to_string(session) + "/runs",
                                         api::StartRunRequestToJson(request));
        const std::int64_t run_id = FromServer(api::RunViewFromJson(started), "run").run_id;
        if (form->detach) {
          if (context.options.json) {
            context.out << started.dump(2) << "\n";
          } else {
            context.out << "started run " << run_id << " (" << form->protocol << ", session "
                        << session << "), detached\n";
          }
          return;
        }
        // With --json, stdout gets one JSON object per line: "started",
        // every stream event, and the final run ("run"); notes go to stderr.
        std::ostream& progress = context.options.json ? context.err : context.out;
        if (context.options.json) {
          JsonLine(context, "started", run_id, started);
        } else {
          progress << "started run " << run_id << " (" << form->protocol << ", session " << session
                   << ")\n"
                   << std::flush;
        }
        // The stop key is for a terminal (StopKey).
        const bool stop_key =
            ::isatty(STDIN_FILENO) && MeasuresMaxTolerated(client, form->protocol);
        FollowRun(context, client, connection, run_id, progress, stop_key);
      };
    });
  }
  {
    auto id = std::make_shared<std::string>();
    CLI::App* show = run->add_subcommand("show", "A run's state, progress, trials and result.");
    show->add_option("run", *id, "run id")->required();
    show->callback([id, &context] {
      context.action = [id, &context] {
        const std::int64_t run_id = ParseId(*id, "run");
        auto client = Connect(context);
        PrintRun(context, client->Get("/runs/" + std::to_string(run_id)));
      };
    });
  }
  AddRunRequest(*run, context, "stop",
                "Stop a run where it is and keep what it recorded: a tolerance test records the "
                "amplitude reached as the max tolerated (clinician or admin).",
                "stop requested (");
  AddRunRequest(*run, context, "cancel", "Cancel a run (stimulation to zero).", "");
  {
    auto clear = std::make_shared<bool>(false);
    CLI::App* estop = app.add_subcommand(
        "estop",
        "Emergency stop: stimulation to zero, motor disabled, latched (--clear to clear).");
    estop->add_flag("--clear", *clear, "clear a latched e-stop (clinician or admin)");
    estop->callback([clear, &context] {
      context.action = [clear, &context] {
        auto client = Connect(context);
        const json state = *clear ? client->Delete("/bench/estop") : client->Post("/bench/estop");
        if (context.options.json) {
          context.out << state.dump(2) << "\n";
          return;
        }
        const api::BenchState bench = FromServer(api::BenchStateFromJson(state), "bench state");
        context.out << (*clear ? "e-stop cleared" : "e-stop latched")
                    << "; bench estopped: " << (bench.estopped ? "yes" : "no") << "\n";
      };
    });
  }
}

}  // namespace fesbench::cli
