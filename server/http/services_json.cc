#include "server/http/services_json.h"

#include <algorithm>

#include "api/json_fields.h"

namespace fesbench::server::http {

using nlohmann::json;

services::Actor ActorOf(const storage::User& user) { return {user.id, user.name, user.role}; }

api::Result<StartRunRequest> StartRunFromJson(const json& body) {
  api::JsonFields f(body);
  StartRunRequest out;
  if (auto protocol = f.String("protocol", true, 64)) out.protocol = *protocol;
  const protocols::ProtocolDescription* description = protocols::FindProtocol(out.protocol);
  if (const auto* parameters = f.Object("parameters", false)) {
    if (parameters->size() > 64) {
      return api::Status::InvalidArgument("too many parameters", "parameters");
    }
    api::JsonFields p(*parameters, "parameters");
    for (const auto& [name, value] : parameters->items()) {
      // A choice parameter takes its name as well as its index.
      if (value.is_string() && description != nullptr) {
        const auto spec =
            std::find_if(description->parameters.begin(), description->parameters.end(),
                         [&](const protocols::ParameterSpec& s) { return s.name == name; });
        if (spec != description->parameters.end() && !spec->choices.empty()) {
          const std::string chosen = value.get<std::string>();
          const auto it = std::find(spec->choices.begin(), spec->choices.end(), chosen);
          if (it == spec->choices.end()) {
            std::string names;
            for (const std::string& c : spec->choices) names += (names.empty() ? "" : ", ") + c;
            return api::Status::InvalidArgument("'" + chosen.substr(0, 40) + "' is not one of " +
                                                    names,
                                                "parameters." + name);
          }
          out.parameters[name] = static_cast<double>(it - spec->choices.begin());
          p.Any(name, true);  // seen
          continue;
        }
      }
      if (auto number = p.Number(name, true)) out.parameters[name] = *number;
    }
    if (auto st = p.Finish(); !st.ok()) return st;
  }
  if (auto reason = f.String("ceiling_reason", false, 500)) out.ceiling_reason = *reason;
  if (const auto* target = f.Object("target_samples", false)) {
    protocols::TargetSamples samples;
    for (const char* key : {"t_s", "angle_deg"}) {
      const std::string field = std::string("target_samples.") + key;
      const auto it = target->find(key);
      if (it == target->end() || !it->is_array()) {
        return api::Status::InvalidArgument("required: an array of numbers", field);
      }
      if (it->size() > kMaxTargetSamples) {
        return api::Status::InvalidArgument(
            "at most " + std::to_string(kMaxTargetSamples) + " samples", field);
      }
      std::vector<double>& values = std::string(key) == "t_s" ? samples.t_s : samples.angle_deg;
      for (std::size_t i = 0; i < it->size(); ++i) {
        if (!(*it)[i].is_number()) {
          return api::Status::InvalidArgument("must be a number", field + "[" +
                                                                      std::to_string(i) + "]");
        }
        values.push_back((*it)[i].get<double>());
      }
    }
    if (target->size() != 2) {
      return api::Status::InvalidArgument("only t_s and angle_deg", "target_samples");
    }
    out.target = std::move(samples);
  }
  if (auto st = f.Finish(); !st.ok()) return st;
  if (description == nullptr) {
    return api::Status(api::ErrorCode::kNotFound, "protocol " + out.protocol + " not found",
                       "protocol");
  }
  return out;
}

}  // namespace fesbench::server::http
