#include "storage/estop_latch.h"

#include "storage/row_helpers.h"

namespace fesbench::storage {

namespace {

api::Status Append(Database& db, bool latched, std::string_view source,
                   std::string_view recorded_by) {
  return db.Write([&](Connection& c) {
    return internal::Execute(
        c,
        "INSERT INTO estop_events (latched, source, recorded_by, at_utc, bench_id)"
        " VALUES (?1, ?2, ?3, ?4, ?5)",
        static_cast<std::int64_t>(latched ? 1 : 0), source, recorded_by, api::FormatUtc(db.Now()),
        db.options().bench_id);
  });
}

}  // namespace

api::Status EStopLatchRepository::RecordLatched(std::string_view source,
                                                std::string_view recorded_by) {
  return Append(db_, true, source, recorded_by);
}

api::Status EStopLatchRepository::RecordCleared(std::string_view recorded_by) {
  return Append(db_, false, "", recorded_by);
}

api::Result<std::optional<LatchedEStop>> EStopLatchRepository::Current() {
  return db_.Read([&](Connection& c) -> api::Result<std::optional<LatchedEStop>> {
    auto rows = internal::QueryRows(
        c,
        "SELECT id, latched, source, recorded_by, at_utc FROM estop_events"
        " WHERE bench_id IN (?1, '') ORDER BY id DESC LIMIT 1",
        [](const Statement& s) -> api::Result<std::optional<LatchedEStop>> {
          if (s.Int64(1) == 0) return std::optional<LatchedEStop>();
          LatchedEStop e;
          e.id = s.Int64(0);
          e.source = s.Text(2);
          e.recorded_by = s.Text(3);
          const auto at = api::ParseUtc(s.Text(4));
          if (!at) return internal::BadStoredValue("e-stop event");
          e.at = *at;
          return std::optional<LatchedEStop>(std::move(e));
        },
        db_.options().bench_id);
    if (!rows.ok()) return rows.status();
    if (rows->empty()) return std::optional<LatchedEStop>();
    return std::move(rows->front());
  });
}

}  // namespace fesbench::storage
