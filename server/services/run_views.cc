#include "server/services/run_service.h"

#include "server/protocols/run_json.h"

// The JSON forms of a run and of the bench state (GET /runs/{id}, GET /bench,
// the runs list, SSE and DDS) — see run_service.h.

namespace fesbench::server::services {
namespace {

nlohmann::json OptionalTime(const std::optional<storage::UtcTime>& t) {
  return t ? nlohmann::json(storage::FormatUtc(*t)) : nlohmann::json(nullptr);
}

template <typename T>
nlohmann::json OptionalValue(const std::optional<T>& v) {
  return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
}

}  // namespace

nlohmann::json RunViewToJson(const RunView& v) {
  nlohmann::json parameters = nlohmann::json::object();
  for (const auto& [k, x] : v.parameters) parameters[k] = x;
  nlohmann::json values = nlohmann::json::object();
  for (const auto& [k, x] : v.values) {
    values[k] = std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr);
  }
  nlohmann::json events = nlohmann::json::array();
  for (const SafetyEvent& e : v.safety_events) events.push_back(protocols::SafetyEventToJson(e));
  const double eta = v.progress.eta_s;
  nlohmann::json j = {
      {"run_id", v.run_id},
      {"session_id", v.session_id},
      {"protocol", v.protocol},
      {"protocol_version", v.protocol_version},
      {"parameters", std::move(parameters)},
      {"state", std::string(protocols::RunStateName(v.state))},
      {"reason", v.reason},
      {"progress", v.progress.fraction},
      {"eta_s", std::isfinite(eta) && eta >= 0.0 ? nlohmann::json(eta) : nlohmann::json(nullptr)},
      {"created_at_utc", storage::FormatUtc(v.created_at)},
      {"started_at_utc", OptionalTime(v.started_at)},
      {"finished_at_utc", OptionalTime(v.finished_at)},
      {"result", v.result},
      {"controller", v.owner.empty() ? nlohmann::json(nullptr) : nlohmann::json(v.owner)},
      {"bench_elapsed_s", v.progress.bench_elapsed_s},
      {"bench_total_s", v.progress.bench_total_s},
      {"trial_ids", v.trial_ids},
      {"parameter_set_id", OptionalValue(v.parameter_set_id)},
      {"values", std::move(values)},
      {"safety_events", std::move(events)},
      {"live", v.live}};
  if (v.tolerance) {
    protocols::RunResult r;
    r.tolerance = v.tolerance;
    j["tolerance"] = protocols::RunResultToJson(r).at("tolerance");
  }
  return j;
}

nlohmann::json BenchStateToJson(const BenchState& s) {
  return {{"kind", s.kind},
          {"mode", s.mode},
          {"busy", s.busy},
          {"estopped", s.estopped},
          {"estop_source", s.estop_source},
          {"owner", s.owner},
          {"owner_user_id", OptionalValue(s.owner_user_id)},
          {"run_id", OptionalValue(s.run_id)},
          {"protocol", s.protocol},
          {"run_state", std::string(protocols::RunStateName(s.run_state))},
          {"progress", protocols::ProgressToJson(s.progress)}};
}

}  // namespace fesbench::server::services
