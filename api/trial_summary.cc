#include "api/trial_summary.h"

#include <utility>

#include "api/json_fields.h"
#include "api/json_read.h"
#include "api/time_utc.h"

namespace fesbench::api {

using nlohmann::json;

std::optional<double> TrialSummary::duration_s() const {
  if (!(sample_rate_hz > 0.0)) return std::nullopt;
  return static_cast<double>(num_samples) / sample_rate_hz;
}

json TrialSummaryToJson(const TrialSummary& t) {
  return {{"id", t.id},
          {"session_id", t.session_id},
          {"run_id", OrNull(t.run_id)},
          {"name", OrNull(t.name)},
          {"kind", t.kind ? json(TrialKindName(*t.kind)) : json(nullptr)},
          {"num_samples", t.num_samples},
          {"sample_rate_hz", t.sample_rate_hz},
          {"duration_s", OrNull(t.duration_s())},
          {"created_at_utc", FormatUtc(t.created_at)}};
}

Result<TrialSummary> TrialSummaryFromJson(const json& j) {
  JsonFields in(j);
  TrialSummary t;
  t.id = in.Integer("id", true).value_or(0);
  ReadInto(in, "session_id", t.session_id);
  ReadInto(in, "run_id", t.run_id);
  ReadInto(in, "name", t.name);
  if (const auto kind = in.String("kind", false)) t.kind = ParseTrialKind(*kind);
  ReadInto(in, "num_samples", t.num_samples);
  ReadInto(in, "sample_rate_hz", t.sample_rate_hz);
  ReadTime(in, "created_at_utc", false, t.created_at);
  return ReadResult(in, std::move(t));
}

json TrialImportRecordToJson(const TrialImportRecord& r) {
  return {{"format", r.format},
          {"source", r.source},
          {"spec", r.spec},
          {"imported_by", r.imported_by},
          {"original_trial_id", OrNull(r.original_trial_id)}};
}

Result<TrialImportRecord> TrialImportRecordFromJson(const json& j) {
  JsonFields in(j);
  TrialImportRecord r;
  ReadInto(in, "format", r.format);
  ReadInto(in, "source", r.source);
  if (const json* spec = in.Any("spec", false)) r.spec = *spec;
  ReadInto(in, "imported_by", r.imported_by);
  ReadInto(in, "original_trial_id", r.original_trial_id);
  return ReadResult(in, std::move(r));
}

Result<std::optional<TrialImportRecord>> TrialImportOf(const json& trial) {
  JsonFields in(trial);
  std::optional<TrialImportRecord> record;
  ReadNested(in, "import", false, record, &TrialImportRecordFromJson);
  return ReadResult(in, std::move(record));
}

}  // namespace fesbench::api
