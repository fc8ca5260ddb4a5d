#include "api/tolerance_run_result.h"

#include "api/json_fields.h"

namespace fesbench::api {

nlohmann::json ToleranceRunResultToJson(const ToleranceRunResult& o) {
  nlohmann::json j = {{"threshold_ma", OrNull(o.threshold_ma)},
                      {"max_tolerated_ma", OrNull(o.max_tolerated_ma)},
                      {"session_revision", OrNull(o.session_revision)}};
  if (o.subject_signalled_limit) j["subject_signalled_limit"] = *o.subject_signalled_limit;
  if (o.ended_at_ceiling) {
    j["ended_at_ceiling"] = true;
    j["message"] = o.message;
  }
  return j;
}

Result<std::optional<ToleranceRunResult>> ToleranceRunResultFromJson(const nlohmann::json& result) {
  if (!result.is_object() || !result.contains("session_revision")) {
    return std::optional<ToleranceRunResult>();
  }
  JsonFields in(result);
  ToleranceRunResult o;
  ReadInto(in, "threshold_ma", o.threshold_ma);
  ReadInto(in, "max_tolerated_ma", o.max_tolerated_ma);
  ReadInto(in, "session_revision", o.session_revision);
  if (const std::optional<bool> signalled = in.Bool("subject_signalled_limit", false)) {
    o.subject_signalled_limit = signalled;
  }
  ReadInto(in, "ended_at_ceiling", o.ended_at_ceiling);
  ReadInto(in, "message", o.message);
  if (!in.ok()) return in.status();
  return std::optional<ToleranceRunResult>(std::move(o));
}

}  // namespace fesbench::api
