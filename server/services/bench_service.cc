#include "server/services/bench_service.h"

#include <cstdint>
#include <exception>
#include <iostream>
#include <optional>
#include <string>
#include <utility>

#include "api/virtual_subject.h"

namespace fesbench::server::services {

nlohmann::json BenchInfoToJson(const BenchInfo& info) {
  const BenchLimits& l = info.limits;
  return {
      {"kind", info.kind},
      {"time_scale", info.time_scale},
      {"simulated", info.simulated},
      {"limits",
       {{"max_stim_ma", l.max_stim_ma},
        {"pulse_rate_hz", l.pulse_rate_hz},
        {"pulse_width_us", l.pulse_width_us},
        {"min_angle_deg", l.min_angle_deg},
        {"max_angle_deg", l.max_angle_deg},
        {"max_motor_torque_nm", l.max_motor_torque_nm},
        {"control_rate_hz", l.control_rate_hz},
        {"sample_rate_hz", l.sample_rate_hz},
        {"emg_rate_hz", l.emg_rate_hz},
        {"max_stop_impact_deg_s", l.max_stop_impact_deg_s}}},
      // The e-stop, owner and run at the top level (the whole picture stays in "state").
      {"estopped", info.state.estopped},
      {"owner",
       info.state.owner.empty() ? nlohmann::json(nullptr) : nlohmann::json(info.state.owner)},
      {"run_id", info.state.run_id ? nlohmann::json(*info.state.run_id) : nlohmann::json(nullptr)},
      {"run_state", info.state.run_id
                        ? nlohmann::json(std::string(protocols::RunStateName(info.state.run_state)))
                        : nlohmann::json(nullptr)},
      {"progress", info.state.progress.fraction},
      {"state", api::BenchStateToJson(info.state)}};
}

BenchService::BenchService(storage::Database& db, RunService& runs,
                           SwappableSimulatedBench* simulated)
    : db_(db), runs_(runs), simulated_(simulated) {}

BenchInfo BenchService::Info() const {
  BenchInfo info;
  info.kind = std::string(runs_.bench().kind());
  info.time_scale = simulated_ != nullptr ? simulated_->time_scale() : runs_.config().time_scale;
  info.limits = runs_.bench().limits();
  info.simulated = simulated_ != nullptr;
  info.state = runs_.State();
  return info;
}

namespace {

// {"draw_seed": N, "family": F}: N a non-negative integer, F "thesis" (the
// default), "analytic" or "plateau", no other key.
struct DrawRequest {
  std::uint64_t seed = 0;
  SubjectFamily family = SubjectFamily::kThesis;
};

api::Result<DrawRequest> DrawRequestFromJson(const nlohmann::json& json) {
  for (const auto& [key, value] : json.items()) {
    if (key != "draw_seed" && key != "family") {
      return api::Status::InvalidArgument("unknown field (a draw takes only draw_seed and family)",
                                          key);
    }
  }
  DrawRequest request;
  const auto found = json.find("draw_seed");
  if (found == json.end()) {
    return api::Status::InvalidArgument("missing required field (the seed of the draw)",
                                        "draw_seed");
  }
  const nlohmann::json& seed = *found;
  if (seed.is_number_unsigned()) {
    request.seed = seed.get<std::uint64_t>();
  } else if (seed.is_number_integer() && seed.get<std::int64_t>() >= 0) {
    request.seed = static_cast<std::uint64_t>(seed.get<std::int64_t>());
  } else {
    return api::Status::InvalidArgument("must be a non-negative integer", "draw_seed");
  }
  if (const auto it = json.find("family"); it != json.end()) {
    const std::optional<SubjectFamily> family =
        it->is_string() ? SubjectFamilyFromName(it->get<std::string>()) : std::nullopt;
    if (!family) {
      return api::Status::InvalidArgument("must be \"thesis\" or \"analytic\"", "family");
    }
    request.family = *family;
  }
  return request;
}

}  // namespace

api::Result<nlohmann::json> BenchService::GetVirtualSubject(const Actor& actor) const {
  if (api::Status st = Require(actor, Permission::kAdminister, "reading the virtual subject");
      !st.ok()) {
    return st;
  }
  if (simulated_ == nullptr) return api::Status::Conflict("not a simulated bench");
  try {
    return VirtualSubjectToJson(simulated_->subject());
  } catch (const std::exception& e) {
    std::cerr << "fesbench-server: bench service: GetVirtualSubject: " << e.what() << std::endl;
    return api::Status::Internal("reading the virtual subject failed");
  }
}

api::Result<nlohmann::json> BenchService::PutVirtualSubject(const Actor& actor,
                                                            const nlohmann::json& json) {
  if (api::Status st = Require(actor, Permission::kAdminister, "replacing the virtual subject");
      !st.ok()) {
    return st;
  }
  if (simulated_ == nullptr) return api::Status::Conflict("not a simulated bench");
  try {
    if (json.is_object() && (json.contains("draw_seed") || json.contains("family"))) {
      api::Result<DrawRequest> draw = DrawRequestFromJson(json);
      if (!draw.ok()) return draw.status();
      return ReplaceVirtualSubject(actor, DrawSubject(draw->seed, draw->family),
                                   "virtual subject drawn from seed " + std::to_string(draw->seed) +
                                       ", family " + std::string(SubjectFamilyName(draw->family)));
    }
    api::Result<VirtualSubject> subject = VirtualSubjectFromJson(json);
    if (!subject.ok()) return subject.status();
    const std::string summary =
        "virtual subject '" + subject->name + "' seed " + std::to_string(subject->seed);
    return ReplaceVirtualSubject(actor, std::move(subject).value(), summary);
  } catch (const std::exception& e) {
    std::cerr << "fesbench-server: bench service: PutVirtualSubject: " << e.what() << std::endl;
    return api::Status::Internal("replacing the virtual subject failed");
  }
}

api::Result<nlohmann::json> BenchService::ReplaceVirtualSubject(const Actor& actor,
                                                                VirtualSubject subject,
                                                                const std::string& summary) {
  api::Status st = runs_.WithIdleBench([&]() -> api::Status {
    // Audit first inside the bench's idle window: if the audit cannot be
    // written the subject stays as it was.
    api::Status audited = db_.Write([&](storage::Connection&) -> api::Status {
      return AppendAudit(db_, actor, "bench.virtual_subject.put", "bench/virtual-subject", summary,
                         "ok");
    });
    if (!audited.ok()) return audited;
    return simulated_->ReplaceSubject(std::move(subject));
  });
  if (!st.ok()) return st;
  return VirtualSubjectToJson(simulated_->subject());
}

}  // namespace fesbench::server::services
