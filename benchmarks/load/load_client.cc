// fesbench load client (performance, README "Benchmarks"): N concurrent analysts fetch
// parameter sets over keep-alive connections for a fixed time while a
// rapid_parameterisation run streams at real time. Reports requests/s,
// p50/p99 latency, requests per connection (every connection must be
// served) and whether the run's event stream lost any sample.
//
//   load_client setup --url http://127.0.0.1:PORT --token ADMIN_TOKEN
//       creates users, a subject, a session and one parameter set (run the
//       server with --time-scale 0 for this); prints "session_id=N
//       parameter_set_id=M clinician=TOKEN analyst=TOKEN".
//   load_client load --url ... --token ADMIN_TOKEN --session N --parameter-set M
//       --clinician TOKEN --analyst TOKEN [--seconds 30] [--connections 32]
//       (server at --time-scale 1).
//   load_client soak --url ... --clinician TOKEN --analyst TOKEN --session N
//       --pid SERVER_PID [--runs 1000] [--every 100]
//       (server at --time-scale 0): rapid runs, each with a prediction and
//       list requests; the server's resident memory every N runs.
// Only loopback URLs are accepted.

#include <httplib.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

struct Target {
  std::string host = "127.0.0.1";
  int port = 8080;
};

bool ParseUrl(const std::string& url, Target& target) {
  const std::string prefix = "http://127.0.0.1:";
  if (url.rfind(prefix, 0) != 0) return false;
  std::string rest = url.substr(prefix.size());
  if (!rest.empty() && rest.back() == '/') rest.pop_back();
  try {
    target.port = std::stoi(rest);
  } catch (...) {
    return false;
  }
  return target.port > 0 && target.port < 65536;
}

httplib::Client MakeClient(const Target& t) {
  httplib::Client c(t.host, t.port);
  c.set_keep_alive(true);
  c.set_read_timeout(60);
  return c;
}

json Request(httplib::Client& c, const std::string& method, const std::string& path,
             const std::string& token, const json& body, int expect) {
  httplib::Headers h{{"Authorization", "Bearer " + token}};
  httplib::Result r{nullptr, httplib::Error::Unknown};
  if (method == "GET") r = c.Get(path, h);
  if (method == "POST") r = c.Post(path, h, body.is_null() ? "" : body.dump(), "application/json");
  if (method == "PUT") r = c.Put(path, h, body.dump(), "application/json");
  if (!r || r->status != expect) {
    throw std::runtime_error(method + " " + path + " failed: " +
                             (r ? std::to_string(r->status) + " " + r->body : "no connection"));
  }
  return json::parse(r->body);
}

std::string NewToken(httplib::Client& c, const std::string& admin, const std::string& name,
                     const std::string& role) {
  auto user = Request(c, "POST", "/api/v1/users", admin, {{"name", name}, {"role", role}}, 201);
  auto token = Request(c, "POST", "/api/v1/tokens", admin, {{"user_id", user["id"]}}, 201);
  return token["token"];
}

// Follows a run's stream: counts samples, checks batches continue each
// other, returns {samples, gaps, dropped, final state}.
struct StreamReport {
  std::uint64_t samples = 0;
  std::uint64_t gaps = 0;
  std::uint64_t dropped = 0;
  std::uint64_t first_sample = 0;
  bool first_seen = false;
  std::string state = "none";
};

StreamReport Follow(const Target& t, const std::string& token, std::int64_t run_id) {
  StreamReport report;
  httplib::Client c = MakeClient(t);
  std::string buffer;
  std::uint64_t next = 0;
  c.Get("/api/v1/runs/" + std::to_string(run_id) + "/stream",
        {{"Authorization", "Bearer " + token}}, [&](const char* data, std::size_t n) {
          buffer.append(data, n);
          std::size_t end;
          while ((end = buffer.find("\n\n")) != std::string::npos) {
            const std::string frame = buffer.substr(0, end);
            buffer.erase(0, end + 2);
            const auto at = frame.find("data: ");
            if (at == std::string::npos) continue;
            const json event = json::parse(frame.substr(at + 6), nullptr, false);
            if (event.is_discarded()) continue;
            const std::string kind = event.value("kind", "");
            if (kind == "samples") {
              const std::uint64_t first = event["first_sample"];
              const std::uint64_t count = event["samples"]["t_s"].size();
              if (!report.first_seen) {
                report.first_seen = true;
                report.first_sample = first;
              } else if (first != next) {
                ++report.gaps;
              }
              next = first + count;
              report.samples += count;
            } else if (kind == "end") {
              report.dropped = event.value("dropped", 0);
              report.state = event.value("state", "");
            }
          }
          return true;
        });
  return report;
}

int Setup(const Target& t, const std::string& admin) {
  auto c = MakeClient(t);
  const std::string clinician = NewToken(c, admin, "load-clinician", "clinician");
  const std::string analyst = NewToken(c, admin, "load-analyst", "analyst");
  auto vs = Request(c, "GET", "/api/v1/bench/virtual-subject", admin, nullptr, 200);
  auto subject =
      Request(c, "POST", "/api/v1/subjects", clinician,
              {{"code", "LOAD-01"},
               {"details",
                {{"weight_kg", vs["anthropometrics"]["body_mass_kg"]},
                 {"shank_length_cm", vs["anthropometrics"]["shank_length_m"].get<double>() * 100}}},
               {"legs", {"right"}}},
              201);
  auto session =
      Request(c, "POST",
              "/api/v1/subjects/" + std::to_string(subject["id"].get<std::int64_t>()) + "/sessions",
              clinician,
              {{"leg", "right"},
               {"date", "2026-11-21"},
               {"threshold_ma", vs["threshold_ma"]},
               {"max_tolerated_ma", vs["max_tolerated_ma"]}},
              201);
  const std::int64_t session_id = session["id"];
  auto run = Request(c, "POST", "/api/v1/sessions/" + std::to_string(session_id) + "/runs",
                     clinician, {{"protocol", "rapid_parameterisation"}}, 201);
  const std::int64_t run_id = run["run_id"];
  json view;
  for (int i = 0; i < 600; ++i) {
    c.Post("/api/v1/runs/" + std::to_string(run_id) + "/heartbeat",
           {{"Authorization", "Bearer " + clinician}}, "", "application/json");
    view = Request(c, "GET", "/api/v1/runs/" + std::to_string(run_id), clinician, nullptr, 200);
    if (view["state"] != "running" && view["state"] != "queued") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  if (!view["parameter_set_id"].is_number_integer()) {
    std::cerr << "setup run did not store a parameter set: " << view.dump() << "\n";
    return 1;
  }
  std::cout << "session_id=" << session_id << " parameter_set_id=" << view["parameter_set_id"]
            << " clinician=" << clinician << " analyst=" << analyst << std::endl;
  return 0;
}

int Load(const Target& t, const std::string& clinician, const std::string& analyst,
         std::int64_t session_id, std::int64_t set_id, int seconds, int connections) {
  // The streaming run, heart-beaten by its clinician.
  auto c = MakeClient(t);
  auto run = Request(c, "POST", "/api/v1/sessions/" + std::to_string(session_id) + "/runs",
                     clinician, {{"protocol", "rapid_parameterisation"}}, 201);
  const std::int64_t run_id = run["run_id"];
  StreamReport stream;
  std::thread follower([&] { stream = Follow(t, analyst, run_id); });
  std::atomic<bool> beating{true};
  std::thread heart([&] {
    auto hc = MakeClient(t);
    while (beating) {
      hc.Post("/api/v1/runs/" + std::to_string(run_id) + "/heartbeat",
              {{"Authorization", "Bearer " + clinician}}, "", "application/json");
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
  });

  const std::string path = "/api/v1/parameter-sets/" + std::to_string(set_id);
  std::vector<std::vector<std::uint32_t>> latencies(static_cast<std::size_t>(connections));
  std::vector<std::uint64_t> errors(static_cast<std::size_t>(connections), 0);
  const auto stop_at = Clock::now() + std::chrono::seconds(seconds);
  std::vector<std::thread> workers;
  for (int i = 0; i < connections; ++i) {
    workers.emplace_back([&, i] {
      auto client = MakeClient(t);
      client.set_read_timeout(10);
      const httplib::Headers h{{"Authorization", "Bearer " + analyst}};
      auto& mine = latencies[static_cast<std::size_t>(i)];
      mine.reserve(1 << 20);
      while (Clock::now() < stop_at) {
        const auto t0 = Clock::now();
        auto r = client.Get(path, h);
        const auto us = std::chrono::duration_cast<std::chrono::microseconds>(Clock::now() - t0);
        if (r && r->status == 200) {
          mine.push_back(static_cast<std::uint32_t>(us.count()));
        } else {
          ++errors[static_cast<std::size_t>(i)];
        }
      }
    });
  }
  const auto started = Clock::now();
  for (auto& w : workers) w.join();
  const double elapsed_s = std::chrono::duration<double>(Clock::now() - started).count();

  follower.join();
  beating = false;
  heart.join();

  std::vector<std::uint32_t> all;
  std::uint64_t min_per_connection = UINT64_MAX, max_per_connection = 0, error_count = 0;
  for (std::size_t i = 0; i < latencies.size(); ++i) {
    all.insert(all.end(), latencies[i].begin(), latencies[i].end());
    min_per_connection = std::min<std::uint64_t>(min_per_connection, latencies[i].size());
    max_per_connection = std::max<std::uint64_t>(max_per_connection, latencies[i].size());
    error_count += errors[i];
  }
  std::sort(all.begin(), all.end());
  auto pct = [&](double p) {
    return all.empty()
               ? 0.0
               : all[static_cast<std::size_t>(p * static_cast<double>(all.size() - 1))] / 1000.0;
  };

  // Samples the run stored, to compare with what the stream delivered.
  auto view = Request(c, "GET", "/api/v1/runs/" + std::to_string(run_id), analyst, nullptr, 200);
  auto trials =
      Request(c, "GET", "/api/v1/sessions/" + std::to_string(session_id) + "/trials?limit=500",
              analyst, nullptr, 200);
  std::uint64_t stored = 0;
  for (const auto& trial : trials["items"]) {
    if (trial["run_id"] == run_id) stored += trial["num_samples"].get<std::uint64_t>();
  }
  const bool all_served = min_per_connection > 0;
  const bool no_sample_lost = stream.state == "done" && stream.gaps == 0 && stream.dropped == 0 &&
                              stream.first_seen && stream.first_sample == 0 &&
                              stream.samples == stored;
  std::printf("connections          %d (keep-alive), %.1f s\n", connections, elapsed_s);
  std::printf("requests             %zu ok, %llu failed\n", all.size(),
              static_cast<unsigned long long>(error_count));
  std::printf("requests/s           %.0f\n", static_cast<double>(all.size()) / elapsed_s);
  std::printf("latency p50 / p99    %.3f ms / %.3f ms (max %.3f ms)\n", pct(0.50), pct(0.99),
              pct(1.0));
  std::printf("per connection       min %llu, max %llu requests; every connection served: %s\n",
              static_cast<unsigned long long>(min_per_connection),
              static_cast<unsigned long long>(max_per_connection), all_served ? "yes" : "NO");
  std::printf(
      "streamed run %lld     state %s, samples streamed %llu / stored %llu, gaps %llu, "
      "dropped %llu; no sample lost: %s\n",
      static_cast<long long>(run_id), stream.state.c_str(),
      static_cast<unsigned long long>(stream.samples), static_cast<unsigned long long>(stored),
      static_cast<unsigned long long>(stream.gaps), static_cast<unsigned long long>(stream.dropped),
      no_sample_lost ? "yes" : "NO");
  (void)view;
  return all_served && no_sample_lost && error_count == 0 ? 0 : 1;
}

// Resident set and its peak of process `pid` in KiB (/proc/PID/status).
struct Memory {
  long rss_kib = -1;
  long hwm_kib = -1;
};

Memory ReadMemory(int pid) {
  Memory m;
  FILE* f = std::fopen(("/proc/" + std::to_string(pid) + "/status").c_str(), "r");
  if (!f) return m;
  char line[256];
  while (std::fgets(line, sizeof line, f)) {
    std::sscanf(line, "VmRSS: %ld kB", &m.rss_kib);
    std::sscanf(line, "VmHWM: %ld kB", &m.hwm_kib);
  }
  std::fclose(f);
  return m;
}

// Waits for job `id` to finish; its final view.
json WaitJob(httplib::Client& c, const std::string& token, std::int64_t id) {
  for (;;) {
    json job = Request(c, "GET", "/api/v1/jobs/" + std::to_string(id), token, nullptr, 200);
    const std::string state = job.value("state", "");
    if (state != "queued" && state != "running") return job;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

// The memory soak: `runs` rapid_parameterisation runs one after
// another on a server at --time-scale 0, each followed by what an analyst
// does with it — a prediction of one of its trials with the new set, and
// the list pages of parameter sets, the session's runs and trials, and
// subjects — printing the server's resident memory every `every` runs.
int Soak(const Target& t, const std::string& clinician, const std::string& analyst,
         std::int64_t session_id, int pid, int runs, int every) {
  auto c = MakeClient(t);
  const std::string session = std::to_string(session_id);
  const auto started = Clock::now();
  const Memory first = ReadMemory(pid);
  if (first.rss_kib < 0) {
    std::cerr << "load_client: cannot read /proc/" << pid << "/status\n";
    return 1;
  }
  std::printf("%8s %10s %10s %10s %12s\n", "runs", "RSS MiB", "peak MiB", "wall s", "s per run");
  std::printf("%8d %10.1f %10.1f %10.1f %12s\n", 0, first.rss_kib / 1024.0, first.hwm_kib / 1024.0,
              0.0, "-");
  std::fflush(stdout);
  auto last_report = Clock::now();
  int failed = 0;
  for (int i = 1; i <= runs; ++i) {
    const json run = Request(c, "POST", "/api/v1/sessions/" + session + "/runs", clinician,
                             {{"protocol", "rapid_parameterisation"}}, 201);
    const std::int64_t run_id = run["run_id"];
    const std::string run_path = "/api/v1/runs/" + std::to_string(run_id);
    json view;
    for (;;) {
      c.Post(run_path + "/heartbeat", {{"Authorization", "Bearer " + clinician}}, "",
             "application/json");
      view = Request(c, "GET", run_path, clinician, nullptr, 200);
      if (view["state"] != "running" && view["state"] != "queued") break;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    if (view["state"] != "done" || !view["parameter_set_id"].is_number_integer()) {
      ++failed;
      continue;
    }
    // A prediction of the run's last trial the set can replay (motor trials are refused).
    bool predicted = false;
    const auto& trial_ids = view["trial_ids"];
    for (auto it = trial_ids.rbegin(); it != trial_ids.rend() && !predicted; ++it) {
      const json body = {{"parameter_set_id", view["parameter_set_id"]}, {"trial_id", *it}};
      auto r = c.Post("/api/v1/predictions", {{"Authorization", "Bearer " + analyst}}, body.dump(),
                      "application/json");
      if (!r || r->status != 202) continue;
      predicted = WaitJob(c, analyst, json::parse(r->body)["id"])["state"] == "done";
    }
    if (!predicted) ++failed;
    Request(c, "GET", "/api/v1/parameter-sets?limit=50", analyst, nullptr, 200);
    Request(c, "GET", "/api/v1/sessions/" + session + "/runs?limit=50", analyst, nullptr, 200);
    Request(c, "GET", "/api/v1/sessions/" + session + "/trials?limit=50", analyst, nullptr, 200);
    Request(c, "GET", "/api/v1/subjects?limit=50", analyst, nullptr, 200);
    if (i % every == 0 || i == runs) {
      const Memory m = ReadMemory(pid);
      const auto now = Clock::now();
      const double block_s = std::chrono::duration<double>(now - last_report).count();
      last_report = now;
      std::printf("%8d %10.1f %10.1f %10.1f %12.3f\n", i, m.rss_kib / 1024.0, m.hwm_kib / 1024.0,
                  std::chrono::duration<double>(now - started).count(),
                  block_s / (i % every == 0 ? every : i % every));
      std::fflush(stdout);
    }
  }
  std::printf("failed runs or predictions: %d\n", failed);
  return failed == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"fesbench HTTP load client (loopback only)"};
  app.require_subcommand(1);
  std::string url, token, clinician, analyst;
  std::int64_t session_id = 0, set_id = 0;
  int seconds = 30, connections = 32;
  auto* setup =
      app.add_subcommand("setup", "create users, a subject, a session and a parameter set");
  setup->add_option("--url", url, "http://127.0.0.1:PORT")->required();
  setup->add_option("--token", token, "admin token")->required();
  auto* load = app.add_subcommand("load", "measure");
  load->add_option("--url", url, "http://127.0.0.1:PORT")->required();
  load->add_option("--clinician", clinician, "clinician token (from setup)")->required();
  load->add_option("--analyst", analyst, "analyst token (from setup)")->required();
  load->add_option("--session", session_id, "session id (from setup)")->required();
  load->add_option("--parameter-set", set_id, "parameter set id (from setup)")->required();
  load->add_option("--seconds", seconds, "measurement time (default 30)")
      ->check(CLI::Range(1, 600));
  load->add_option("--connections", connections, "concurrent analysts (default 32)")
      ->check(CLI::Range(1, 512));
  auto* soak = app.add_subcommand("soak", "resident memory of the server over many runs");
  int pid = 0, runs = 1000, every = 100;
  soak->add_option("--url", url, "http://127.0.0.1:PORT")->required();
  soak->add_option("--clinician", clinician, "clinician token (from setup)")->required();
  soak->add_option("--analyst", analyst, "analyst token (from setup)")->required();
  soak->add_option("--session", session_id, "session id (from setup)")->required();
  soak->add_option("--pid", pid, "the server's process id (its memory is read)")->required();
  soak->add_option("--runs", runs, "rapid runs (default 1000)")->check(CLI::Range(1, 100000));
  soak->add_option("--every", every, "report every N runs (default 100)")
      ->check(CLI::Range(1, 100000));
  CLI11_PARSE(app, argc, argv);
  Target target;
  if (!ParseUrl(url, target)) {
    std::cerr << "load_client: the URL must be http://127.0.0.1:PORT\n";
    return 2;
  }
  try {
    if (*setup) return Setup(target, token);
    if (*soak) return Soak(target, clinician, analyst, session_id, pid, runs, every);
    return Load(target, clinician, analyst, session_id, set_id, seconds, connections);
  } catch (const std::exception& e) {
    std::cerr << "load_client: " << e.what() << "\n";
    return 1;
  }
}
