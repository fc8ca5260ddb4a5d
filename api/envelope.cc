#include "api/envelope.h"

#include "api/job.h"
#include "api/json_fields.h"

namespace fesbench::api {

using nlohmann::json;

json PageToJson(const Page& page) {
  return {{"items", page.items}, {"next_cursor", OrNull(page.next_cursor)}};
}

Result<Page> PageFromJson(const json& j) {
  JsonFields in(j);
  Page page;
  if (const json* items = in.Any("items", true)) {
    if (!items->is_array()) {
      in.Fail("items", "must be an array");
    } else {
      page.items.assign(items->begin(), items->end());
    }
  }
  if (const json* cursor = in.Any("next_cursor", false); cursor && cursor->is_string()) {
    page.next_cursor = cursor->get<std::string>();
  }
  if (!in.ok()) return in.status();
  return page;
}

std::optional<Status> ErrorAnswerFromJson(const json& body) {
  if (!body.is_object()) return std::nullopt;
  JsonFields in(body);
  const json* error = in.Object("error", true);
  if (error == nullptr) return std::nullopt;
  return ErrorFromJson(*error);
}

json ErrorAnswerToJson(const Status& status) { return {{"error", ErrorToJson(status)}}; }

}  // namespace fesbench::api
