// `fesbench run start|show|cancel` and `fesbench estop`: protocol runs on the
// bench (DESIGN.md §5, §6, §8). `run start --follow` follows the run's event
// stream to its end while heart-beating it, because the server's watchdog
// stops a run whose controlling user goes silent for more than a second.

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <map>
#include <memory>
#include <mutex>
#include <ostream>
#include <string>
#include <thread>
#include <vector>

#include "clients/cli/commands.h"
#include "clients/cli/config.h"
#include "clients/cli/output.h"

namespace fesbench::cli {

namespace {

using nlohmann::json;

constexpr auto kHeartbeatPeriod = std::chrono::milliseconds(250);
constexpr int kBarWidth = 30;

std::string FormatEta(const json& eta_s) {
  if (!eta_s.is_number()) return "--";
  const double s = std::max(0.0, eta_s.get<double>());
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

  void Progress(const json& progress) {
    if (!progress.is_object()) return;
    const double fraction = std::clamp(progress.value("fraction", 0.0), 0.0, 1.0);
    const int percent = static_cast<int>(std::floor(fraction * 100.0));
    const std::string phase = progress.value("phase", "");
    const std::string eta = FormatEta(progress.contains("eta_s") ? progress["eta_s"] : json());
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
    out_ << "progress " << percent << "% eta " << eta << " step " << progress.value("step", 0)
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

// Follows a run's stream to its end; throws CliError unless it ends "done".
void FollowRun(CliContext& context, ApiClient& client, const CliConfig& connection,
               std::int64_t run_id) {
  Heartbeat heartbeat(connection, run_id);
  ProgressPrinter printer(context.out, context.out_is_terminal);
  json end;
  std::string last_state;
  client.Stream("/runs/" + std::to_string(run_id) + "/stream",
                [&](const std::string& event, const json& data) {
                  if (!data.is_object()) return true;
                  if (event == "state") {
                    const std::string state = data.value("state", "");
                    if (state != last_state) {
                      last_state = state;
                      printer.Line("state " + state);
                    }
                    if (data.contains("progress")) printer.Progress(data["progress"]);
                  } else if (event == "progress") {
                    printer.Progress(data["progress"]);
                  } else if (event == "trial") {
                    printer.Line("trial " + Cell(data.value("trial_name", json(nullptr))) +
                                 " stored as trial " + Cell(data.value("trial_id", json(nullptr))));
                  } else if (event == "end") {
                    end = data;
                    return false;
                  }
                  return true;
                });
  if (end.is_null()) {
    throw CliError::Unreachable("the event stream of run " + std::to_string(run_id) +
                                " closed before the run ended");
  }
  const std::string state = end.value("state", "");
  std::string line = "end " + state;
  if (end.contains("parameter_set_id") && end["parameter_set_id"].is_number_integer()) {
    line += " parameter_set " + Cell(end["parameter_set_id"]);
  }
  printer.Line(line);
  if (state != "done") {
    std::string reason = end.value("reason", "");
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

struct StartForm {
  std::string session;
  std::string protocol;
  std::vector<std::string> params;
  bool follow = false;
};

}  // namespace

void RegisterRunCommands(CLI::App& app, CliContext& context) {
  CLI::App* run = app.add_subcommand("run", "Protocol runs: start, show, cancel.");
  run->require_subcommand(1);
  {
    auto form = std::make_shared<StartForm>();
    CLI::App* start = run->add_subcommand(
        "start", "Start a protocol for a session (clinician or admin); --follow to watch it.");
    start->add_option("session", form->session, "session id")->required();
    start->add_option("protocol", form->protocol, "protocol name, e.g. rapid_parameterisation")
        ->required();
    start->add_option("--param", form->params, "protocol parameter key=value (repeatable)");
    start->add_flag("--follow", form->follow,
                    "follow the run to its end (progress bar on a terminal, lines when piped)");
    start->callback([form, &context] {
      context.action = [form, &context] {
        const std::int64_t session = ParseId(form->session, "session");
        json parameters = json::object();
        for (const auto& text : form->params) {
          const auto [key, value] = ParseKeyValue(text);
          parameters[key] = value;
        }
        const CliConfig connection = ResolveConnection(context.options);
        ApiClient client(connection);
        const json started =
            client.Post("/sessions/" + std::to_string(session) + "/runs",
                        {{"protocol", form->protocol}, {"parameters", parameters}});
        const std::int64_t run_id = started["run_id"].get<std::int64_t>();
        if (context.options.json && !form->follow) {
          context.out << started.dump(2) << "\n";
          return;
        }
        context.out << "started run " << run_id << " (" << form->protocol << ", session " << session
                    << ")\n"
                    << std::flush;
        if (form->follow) FollowRun(context, client, connection, run_id);
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
  {
    auto id = std::make_shared<std::string>();
    CLI::App* cancel = run->add_subcommand("cancel", "Cancel a run (stimulation to zero).");
    cancel->add_option("run", *id, "run id")->required();
    cancel->callback([id, &context] {
      context.action = [id, &context] {
        const std::int64_t run_id = ParseId(*id, "run");
        auto client = Connect(context);
        const json view = client->Post("/runs/" + std::to_string(run_id) + "/cancel");
        context.out << "run " << run_id << ": " << Cell(view.value("state", json(nullptr))) << "\n";
      };
    });
  }
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
        context.out << (*clear ? "e-stop cleared" : "e-stop latched")
                    << "; bench estopped: " << Cell(state.value("estopped", json(nullptr))) << "\n";
      };
    });
  }
}

}  // namespace fesbench::cli
