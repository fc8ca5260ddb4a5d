#include "server/http/services_json.h"

#include <algorithm>

#include "api/json_fields.h"

namespace fesbench::server::http {

using nlohmann::json;

services::Actor ActorOf(const storage::User& user) { return {user.id, user.name, user.role}; }

api::Result<StartRunRequest> StartRunFromJson(const json& body) {
  api::Result<StartRunRequest> request = api::StartRunRequestFromJson(body);
  if (!request.ok()) return request;
  const protocols::ProtocolDescription* description = protocols::FindProtocol(request->protocol);
  if (description == nullptr) {
    return api::Status(api::ErrorCode::kNotFound, "protocol " + request->protocol + " not found",
                       "protocol");
  }
  // A choice parameter takes its name as well as its index.
  for (const auto& [name, chosen] : request->choices) {
    const std::string field = "parameters." + name;
    const auto spec = std::find_if(
        description->parameters.begin(), description->parameters.end(),
        [&](const protocols::ParameterSpec& s) { return s.name == name; });
    if (spec == description->parameters.end() || spec->choices.empty()) {
      return api::Status::InvalidArgument("must be a number, got string", field);
    }
    const auto it = std::find(spec->choices.begin(), spec->choices.end(), chosen);
    if (it == spec->choices.end()) {
      std::string names;
      for (const std::string& c : spec->choices) names += (names.empty() ? "" : ", ") + c;
      return api::Status::InvalidArgument(
          "'" + chosen.substr(0, 40) + "' is not one of " + names, field);
    }
    request->parameters[name] = static_cast<double>(it - spec->choices.begin());
  }
  request->choices.clear();
  return request;
}

}  // namespace fesbench::server::http
