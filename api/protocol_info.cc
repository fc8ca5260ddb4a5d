#include "api/protocol_info.h"

#include <utility>

#include "api/json_fields.h"

namespace fesbench::api {

using nlohmann::json;

json ProtocolInfoToJson(const ProtocolInfo& protocol) {
  json parameters = json::array();
  for (const ProtocolParameterInfo& p : protocol.parameters) {
    parameters.push_back({{"name", p.name},
                          {"label", p.label},
                          {"unit", p.unit},
                          {"description", p.description},
                          {"default", OrNull(p.default_value)},
                          {"default_rule", OrNull(p.default_rule)},
                          {"min", p.min},
                          {"max", p.max},
                          {"integer", p.integer},
                          {"advanced", p.advanced},
                          {"scales_to", p.scales_to},
                          {"rest", p.rest},
                          {"choices", p.choices}});
  }
  return {{"name", protocol.name},
          {"version", protocol.version},
          {"title", protocol.title},
          {"description", protocol.description},
          {"thesis_section", protocol.thesis_section},
          {"stimulates", protocol.stimulates},
          {"bench_mode", protocol.bench_mode},
          {"min_rest_s", protocol.min_rest_s},
          {"measures_max_tolerated", protocol.measures_max_tolerated},
          {"follows_target", protocol.follows_target},
          {"offered_first", protocol.offered_first},
          {"parameters", std::move(parameters)}};
}

Result<ProtocolInfo> ProtocolInfoFromJson(const json& j) {
  JsonFields in(j);
  ProtocolInfo protocol;
  protocol.name = in.String("name", true).value_or("");
  ReadInto(in, "version", protocol.version);
  ReadInto(in, "title", protocol.title);
  ReadInto(in, "description", protocol.description);
  ReadInto(in, "thesis_section", protocol.thesis_section);
  ReadInto(in, "stimulates", protocol.stimulates);
  ReadInto(in, "bench_mode", protocol.bench_mode);
  ReadInto(in, "min_rest_s", protocol.min_rest_s);
  ReadInto(in, "measures_max_tolerated", protocol.measures_max_tolerated);
  ReadInto(in, "follows_target", protocol.follows_target);
  ReadInto(in, "offered_first", protocol.offered_first);
  const json* parameters = in.Any("parameters", false);
  if (parameters != nullptr && !parameters->is_array()) in.Fail("parameters", "must be a list");
  for (std::size_t i = 0; in.ok() && parameters != nullptr && i < parameters->size(); ++i) {
    JsonFields f((*parameters)[i], "parameters[" + std::to_string(i) + "]");
    ProtocolParameterInfo p;
    p.name = f.String("name", true).value_or("");
    ReadInto(f, "label", p.label);
    ReadInto(f, "unit", p.unit);
    ReadInto(f, "description", p.description);
    ReadInto(f, "default", p.default_value);
    ReadInto(f, "default_rule", p.default_rule);
    ReadInto(f, "min", p.min);
    ReadInto(f, "max", p.max);
    ReadInto(f, "integer", p.integer);
    ReadInto(f, "advanced", p.advanced);
    ReadInto(f, "scales_to", p.scales_to);
    ReadInto(f, "rest", p.rest);
    ReadInto(f, "choices", p.choices);
    if (!f.ok()) return f.status();
    protocol.parameters.push_back(std::move(p));
  }
  if (!in.ok()) return in.status();
  return protocol;
}

json ProtocolCatalogueToJson(const std::vector<ProtocolInfo>& protocols) {
  json list = json::array();
  for (const ProtocolInfo& p : protocols) list.push_back(ProtocolInfoToJson(p));
  return {{"protocols", std::move(list)}};
}

Result<std::vector<ProtocolInfo>> ProtocolCatalogueFromJson(const json& j) {
  JsonFields in(j);
  const json* list = in.Any("protocols", true);
  if (list != nullptr && !list->is_array()) in.Fail("protocols", "must be a list");
  if (!in.ok()) return in.status();
  std::vector<ProtocolInfo> protocols;
  for (std::size_t i = 0; i < list->size(); ++i) {
    Result<ProtocolInfo> p = ProtocolInfoFromJson((*list)[i]);
    if (!p.ok()) {
      const std::string& field = p.status().field();
      return Status::InvalidArgument(p.status().message(), "protocols[" + std::to_string(i) + "]" +
                                                               (field.empty() ? "" : "." + field));
    }
    protocols.push_back(*std::move(p));
  }
  return protocols;
}

}  // namespace fesbench::api
