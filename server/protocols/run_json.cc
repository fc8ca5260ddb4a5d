#include "server/protocols/run_json.h"

#include <cmath>

#include "api/parameter_set_json.h"

namespace fesbench::server::protocols {
namespace {

nlohmann::json Number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

}  // namespace

nlohmann::json RunResultToJson(const RunResult& r) {
  nlohmann::json trials = nlohmann::json::array();
  for (const RecordedTrial& t : r.trials) {
    const std::size_t n = t.trial.num_samples();
    trials.push_back({{"name", t.trial.name.value_or("")},
                      {"samples", n},
                      {"sample_rate_hz", t.trial.sample_rate_hz},
                      {"duration_s", static_cast<double>(n) / t.trial.sample_rate_hz},
                      {"complete", t.complete},
                      {"offsets_nm", t.offsets_nm}});
  }
  nlohmann::json events = nlohmann::json::array();
  for (const SafetyEvent& e : r.safety_events) events.push_back(api::SafetyEventToJson(e));
  nlohmann::json parameters = nlohmann::json::object();
  for (const auto& [k, v] : r.parameters) parameters[k] = v;
  nlohmann::json values = nlohmann::json::object();
  for (const auto& [k, v] : r.values) values[k] = Number(v);
  nlohmann::json j = {{"state", std::string(RunStateName(r.state))},
                      {"reason", r.reason},
                      {"protocol", r.protocol},
                      {"protocol_version", r.protocol_version},
                      {"parameters", std::move(parameters)},
                      {"trials", std::move(trials)},
                      {"values", std::move(values)},
                      {"safety_events", std::move(events)},
                      {"bench_duration_s", r.bench_duration_s},
                      {"wall_duration_s", r.wall_duration_s}};
  if (r.tolerance) j["tolerance"] = api::ToleranceResultToJson(*r.tolerance);
  if (r.parameter_set) j["parameter_set"] = api::ParameterSetToJson(*r.parameter_set);
  return j;
}

}  // namespace fesbench::server::protocols
