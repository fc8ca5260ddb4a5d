#include "api/job.h"

#include "api/json_fields.h"
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
  JsonFields in(error);
  ErrorCode code = ErrorCode::kInternal;
  std::string message = "no message";
  std::string field;
  ReadInto(in, "message", message);
  ReadInto(in, "field", field);
  ReadNamed(in, "code", false, code, &ParseErrorCode);  // last: an unknown code keeps the text
  if (!in.ok() || code == ErrorCode::kOk) code = ErrorCode::kInternal;
  return {code, std::move(message), std::move(field)};
}

Result<JobReport> JobReportFromJson(const nlohmann::json& job) {
  JsonFields in(job);
  JobReport report;
  report.id = in.Integer("id", true).value_or(0);
  ReadNamed(in, "state", true, report.state, &ParseJobState);
  ReadInto(in, "kind", report.kind);
  if (!in.ok()) return in.status();
  if (report.state == JobState::kDone) report.result = job.value("result", nlohmann::json());
  if (report.state == JobState::kFailed) {
    report.error = ErrorFromJson(job.value("error", nlohmann::json()));
  }
  return report;
}

}  // namespace fesbench::api
