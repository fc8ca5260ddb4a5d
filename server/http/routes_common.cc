#include "server/http/routes_common.h"

#include <charconv>

#include "server/http/resources_json.h"
#include "storage/audit_log.h"

namespace fesbench::server::http {

namespace {

constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_";

std::string Base64Url(std::string_view in) {
  std::string out;
  std::uint32_t buffer = 0;
  int bits = 0;
  for (unsigned char c : in) {
    buffer = (buffer << 8) | c;
    bits += 8;
    while (bits >= 6) {
      bits -= 6;
      out.push_back(kAlphabet[(buffer >> bits) & 0x3F]);
    }
  }
  if (bits > 0) out.push_back(kAlphabet[(buffer << (6 - bits)) & 0x3F]);
  return out;
}

std::optional<std::string> FromBase64Url(std::string_view in) {
  std::string out;
  std::uint32_t buffer = 0;
  int bits = 0;
  for (char c : in) {
    const char* p = std::char_traits<char>::find(kAlphabet, 64, c);
    if (!p) return std::nullopt;
    buffer = (buffer << 6) | static_cast<std::uint32_t>(p - kAlphabet);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<char>((buffer >> bits) & 0xFF));
    }
  }
  return out;
}

std::optional<std::int64_t> ParseId(std::string_view text) {
  std::int64_t value = 0;
  if (text.empty() || text.size() > 18) return std::nullopt;
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || value < 0) return std::nullopt;
  return value;
}

}  // namespace

std::vector<QueryParam> PageParams() {
  return {{"limit", "integer", "page size, 1–500 (default 50)"},
          {"cursor", "string", "opaque cursor from a previous page's next_cursor"}};
}

std::string EncodeCursor(std::int64_t after_id) {
  return Base64Url("after:" + std::to_string(after_id));
}

std::optional<std::int64_t> DecodeCursor(std::string_view cursor) {
  if (cursor.size() > 64) return std::nullopt;
  auto text = FromBase64Url(cursor);
  if (!text || text->rfind("after:", 0) != 0) return std::nullopt;
  return ParseId(std::string_view(*text).substr(6));
}

api::Result<PageRequest> ParsePage(const RequestContext& ctx) {
  PageRequest page;
  if (auto limit = ctx.Query("limit")) {
    auto value = ParseId(*limit);
    if (!value || *value < 1 || *value > static_cast<std::int64_t>(kMaxPageLimit)) {
      return api::Status::InvalidArgument("must be an integer in [1, 500]", "limit");
    }
    page.limit = static_cast<std::size_t>(*value);
  }
  if (auto cursor = ctx.Query("cursor")) {
    auto after = DecodeCursor(*cursor);
    if (!after) return api::Status::InvalidArgument("is not a cursor this server issued", "cursor");
    page.after_id = *after;
  }
  return page;
}

api::Result<std::optional<std::int64_t>> QueryId(const RequestContext& ctx,
                                                 const std::string& name) {
  auto text = ctx.Query(name);
  if (!text) return std::optional<std::int64_t>();
  auto value = ParseId(*text);
  if (!value || *value < 1)
    return api::Status::InvalidArgument("must be a positive integer id", name);
  return std::optional<std::int64_t>(*value);
}

api::Result<std::optional<api::UtcTime>> QueryTime(const RequestContext& ctx,
                                                       const std::string& name) {
  auto text = ctx.Query(name);
  if (!text) return std::optional<api::UtcTime>();
  if (api::IsIsoDate(*text)) {
    auto t = api::ParseUtc(*text + "T00:00:00.000000Z");
    if (t) return std::optional<api::UtcTime>(*t);
  }
  if (auto t = api::ParseUtc(*text)) return std::optional<api::UtcTime>(*t);
  return api::Status::InvalidArgument(
      "must be a date YYYY-MM-DD or a UTC time YYYY-MM-DDTHH:MM:SS.ffffffZ", name);
}

nlohmann::json ObjectSchema(nlohmann::json properties, std::vector<std::string> required) {
  nlohmann::json schema = {
      {"type", "object"}, {"additionalProperties", false}, {"properties", std::move(properties)}};
  if (!required.empty()) schema["required"] = std::move(required);
  return schema;
}

api::Result<nlohmann::json> SubjectJson(storage::Database& db, const storage::Subject& subject) {
  auto legs = storage::SubjectRepository(db).Legs(subject.id);
  if (!legs.ok()) return legs.status();
  return api::SubjectToJson(storage::SubjectResource(subject, *legs));
}

api::Result<nlohmann::json> SessionJson(storage::Database& db, const storage::Session& session) {
  auto leg = storage::SubjectRepository(db).GetLeg(session.leg_id);
  if (!leg.ok()) return leg.status();
  return api::SessionToJson(storage::SessionResource(session, leg->side));
}

api::Result<nlohmann::json> AuditedCorrection(storage::Database& db, RequestContext& ctx,
                                    const std::string& target, const std::string& reason,
                                    const std::vector<std::string>& changed,
                                    const nlohmann::json& new_details,
                                    const std::function<api::Result<nlohmann::json>()>& write) {
  std::string summary = "reason: " + reason + "; changed:";
  for (const std::string& key : changed) {
    summary += " " + key + "=" + (new_details.contains(key) ? new_details.at(key).dump() : "null");
  }
  auto result = db.Write([&](storage::Connection&) -> api::Result<nlohmann::json> {
    api::Result<nlohmann::json> value = write();
    if (!value.ok()) return value;
    auto appended = storage::AuditLog(db).Append(
        {ctx.user ? std::optional<std::int64_t>(ctx.user->id) : std::nullopt,
         ctx.user ? ctx.user->name : std::string("anonymous"), ctx.req.method + " " + ctx.req.path,
         target, summary, "200"});
    if (!appended.ok()) return appended.status();
    return value;
  });
  return result;
}

nlohmann::json CorrectionSchema(nlohmann::json details) {
  return ObjectSchema({{"reason", {{"type", "string"}, {"minLength", 1}, {"maxLength", 500}}},
                       {"details", std::move(details)}},
                      {"reason", "details"});
}

}  // namespace fesbench::server::http
