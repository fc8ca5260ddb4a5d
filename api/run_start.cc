#include "api/run_start.h"

#include <utility>

#include "api/json_fields.h"

namespace fesbench::api {
namespace {

using nlohmann::json;

Status ReadTarget(const json& target, TargetSamples& out) {
  for (const char* key : {"t_s", "angle_deg"}) {
    const std::string field = std::string("target_samples.") + key;
    const auto it = target.find(key);
    if (it == target.end() || !it->is_array()) {
      return Status::InvalidArgument("required: an array of numbers", field);
    }
    if (it->size() > kMaxTargetSamples) {
      return Status::InvalidArgument("at most " + std::to_string(kMaxTargetSamples) + " samples",
                                     field);
    }
    std::vector<double>& values = std::string(key) == "t_s" ? out.t_s : out.angle_deg;
    for (std::size_t i = 0; i < it->size(); ++i) {
      if (!(*it)[i].is_number()) {
        return Status::InvalidArgument("must be a number", field + "[" + std::to_string(i) + "]");
      }
      values.push_back((*it)[i].get<double>());
    }
  }
  if (target.size() != 2)
    return Status::InvalidArgument("only t_s and angle_deg", "target_samples");
  return Status::Ok();
}

}  // namespace

Result<StartRunRequest> StartRunRequestFromJson(const json& body) {
  JsonFields f(body);
  StartRunRequest out;
  out.protocol = f.String("protocol", true, 64).value_or("");
  if (const json* parameters = f.Object("parameters", false)) {
    if (parameters->size() > kMaxRunParameters) {
      return Status::InvalidArgument("too many parameters", "parameters");
    }
    JsonFields p(*parameters, "parameters");
    for (const auto& [name, value] : parameters->items()) {
      if (value.is_string()) {
        // Unset when the name is too long or an earlier parameter failed.
        if (auto choice = p.String(name, true, 64)) out.choices[name] = std::move(*choice);
      } else if (const auto number = p.Number(name, true)) {
        out.parameters[name] = *number;
      }
    }
    if (Status s = p.Finish(); !s.ok()) return s;
  }
  out.ceiling_reason = f.String("ceiling_reason", false, 500);
  if (const json* target = f.Object("target_samples", false)) {
    TargetSamples samples;
    if (Status s = ReadTarget(*target, samples); !s.ok()) return s;
    out.target = std::move(samples);
  }
  if (Status s = f.Finish(); !s.ok()) return s;
  return out;
}

json StartRunRequestToJson(const StartRunRequest& request) {
  json parameters = json::object();
  for (const auto& [name, value] : request.parameters) parameters[name] = value;
  for (const auto& [name, choice] : request.choices) parameters[name] = choice;
  json body = {{"protocol", request.protocol}, {"parameters", std::move(parameters)}};
  if (request.ceiling_reason) body["ceiling_reason"] = *request.ceiling_reason;
  if (request.target) {
    body["target_samples"] = {{"t_s", request.target->t_s},
                              {"angle_deg", request.target->angle_deg}};
  }
  return body;
}

}  // namespace fesbench::api
