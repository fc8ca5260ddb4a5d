#include "server/http/services_json.h"

#include "server/http/json_fields.h"

namespace fesbench::server::http {

using nlohmann::json;

services::Actor ActorOf(const storage::User& user) { return {user.id, user.name, user.role}; }

api::Result<StartRunRequest> StartRunFromJson(const json& body) {
  JsonFields f(body);
  StartRunRequest out;
  if (auto protocol = f.String("protocol", true, 64)) out.protocol = *protocol;
  if (const auto* parameters = f.Object("parameters", false)) {
    if (parameters->size() > 64) {
      return api::Status::InvalidArgument("too many parameters", "parameters");
    }
    JsonFields p(*parameters, "parameters");
    for (const auto& [name, value] : parameters->items()) {
      if (auto number = p.Number(name, true)) out.parameters[name] = *number;
    }
    if (auto st = p.Finish(); !st.ok()) return st;
  }
  if (auto reason = f.String("ceiling_reason", false, 500)) out.ceiling_reason = *reason;
  if (auto st = f.Finish(); !st.ok()) return st;
  if (!protocols::FindProtocol(out.protocol)) {
    return api::Status(api::ErrorCode::kNotFound, "protocol " + out.protocol + " not found",
                       "protocol");
  }
  return out;
}

}  // namespace fesbench::server::http
