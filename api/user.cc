#include "api/user.h"

#include <utility>

#include "api/json_fields.h"
#include "api/json_read.h"
#include "api/name_table.h"
#include "api/time_utc.h"

namespace fesbench::api {
namespace {

using nlohmann::json;

constexpr NameTable<Role, 3> kRoles(
    {{{Role::kClinician, "clinician"}, {Role::kAnalyst, "analyst"}, {Role::kAdmin, "admin"}}},
    "analyst");

}  // namespace

std::string_view RoleName(Role role) { return kRoles.Name(role); }
std::optional<Role> ParseRole(std::string_view name) { return kRoles.Parse(name); }

json UserToJson(const User& u) {
  return {{"id", u.id},
          {"name", u.name},
          {"role", RoleName(u.role)},
          {"active", u.active},
          {"created_at_utc", FormatUtc(u.created_at)}};
}

json SignedInUserToJson(const User& u) {
  return {{"id", u.id}, {"name", u.name}, {"role", std::string(RoleName(u.role))}};
}

Result<User> UserFromJson(const json& j) {
  JsonFields in(j);
  User u;
  u.id = in.Integer("id", true).value_or(0);
  ReadInto(in, "name", u.name);
  ReadNamed(in, "role", false, u.role, &ParseRole);
  ReadInto(in, "active", u.active);
  ReadTime(in, "created_at_utc", false, u.created_at);
  return ReadResult(in, std::move(u));
}

json TokenInfoToJson(const TokenInfo& t) {
  return {{"id", t.id},
          {"user_id", t.user_id},
          {"user_name", t.user_name},
          {"label", t.label},
          {"created_at_utc", t.created_at_utc},
          {"expires_at_utc", OrNull(t.expires_at_utc)},
          {"revoked", t.revoked_at_utc.has_value()},
          {"revoked_at_utc", OrNull(t.revoked_at_utc)}};
}

Result<TokenInfo> TokenInfoFromJson(const json& j) {
  JsonFields in(j);
  TokenInfo t;
  t.id = in.Integer("id", true).value_or(0);
  ReadInto(in, "user_id", t.user_id);
  ReadInto(in, "user_name", t.user_name);
  ReadInto(in, "label", t.label);
  ReadInto(in, "created_at_utc", t.created_at_utc);
  ReadInto(in, "expires_at_utc", t.expires_at_utc);
  ReadInto(in, "revoked_at_utc", t.revoked_at_utc);
  in.Any("revoked", false);  // follows from revoked_at_utc
  return ReadResult(in, std::move(t));
}

json IssuedTokenToJson(const IssuedTokenView& t) {
  return {{"id", t.id},
          {"user_id", t.user_id},
          {"label", t.label},
          {"token", t.token},
          {"expires_at_utc", t.expires_at ? json(FormatUtc(*t.expires_at)) : json(nullptr)}};
}

Result<IssuedTokenView> IssuedTokenFromJson(const json& j) {
  JsonFields in(j);
  IssuedTokenView t;
  t.id = in.Integer("id", true).value_or(0);
  ReadInto(in, "user_id", t.user_id);
  ReadInto(in, "label", t.label);
  ReadInto(in, "token", t.token);
  ReadTime(in, "expires_at_utc", t.expires_at);
  return ReadResult(in, std::move(t));
}

json NewUserRequestToJson(const NewUserRequest& request) {
  return {{"name", request.name}, {"role", RoleName(request.role)}};
}

json NewTokenRequestToJson(const NewTokenRequest& request) {
  json body = {{"user_id", request.user_id}};
  if (!request.label.empty()) body["label"] = request.label;
  if (request.expires_in_s) body["expires_in_s"] = *request.expires_in_s;
  return body;
}

}  // namespace fesbench::api
