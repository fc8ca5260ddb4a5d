#include "api/job.h"

#include "api/name_table.h"

namespace fesbench::api {

namespace {

constexpr NameTable<JobState, 4> kJobStates({{{JobState::kQueued, "queued"},
                                              {JobState::kRunning, "running"},
                                              {JobState::kDone, "done"},
                                              {JobState::kFailed, "failed"}}},
                                            "failed");

}  // namespace

std::string_view JobStateName(JobState state) { return kJobStates.Name(state); }

std::optional<JobState> ParseJobState(std::string_view name) { return kJobStates.Parse(name); }

nlohmann::json ErrorToJson(const Status& status) {
  nlohmann::json error = {{"code", ErrorCodeName(status.code())}, {"message", status.message()}};
  if (!status.field().empty()) error["field"] = status.field();
  return error;
}

Status ErrorFromJson(const nlohmann::json& error) {
  if (!error.is_object()) return Status::Internal("malformed error object: " + error.dump());
  const auto text = [&](const char* key) {
    const auto it = error.find(key);
    return it != error.end() && it->is_string() ? it->get<std::string>() : std::string();
  };
  const ErrorCode code = ParseErrorCode(text("code")).value_or(ErrorCode::kInternal);
  std::string message = text("message");
  if (message.empty()) message = "no message";
  return {code == ErrorCode::kOk ? ErrorCode::kInternal : code, std::move(message), text("field")};
}

Result<JobReport> JobReportFromJson(const nlohmann::json& job) {
  if (!job.is_object()) return Status::InvalidArgument("must be a job object", "job");
  JobReport report;
  const auto id = job.find("id");
  if (id == job.end() || !id->is_number_integer()) {
    return Status::InvalidArgument("a job needs an integer id", "id");
  }
  report.id = id->get<std::int64_t>();
  const auto state = job.find("state");
  const std::optional<JobState> parsed = state != job.end() && state->is_string()
                                             ? ParseJobState(state->get<std::string>())
                                             : std::nullopt;
  if (!parsed) return Status::InvalidArgument("must be queued, running, done or failed", "state");
  report.state = *parsed;
  if (const auto kind = job.find("kind"); kind != job.end() && kind->is_string()) {
    report.kind = kind->get<std::string>();
  }
  if (report.state == JobState::kDone) report.result = job.value("result", nlohmann::json());
  if (report.state == JobState::kFailed) {
    report.error = ErrorFromJson(job.value("error", nlohmann::json()));
  }
  return report;
}

}  // namespace fesbench::api
