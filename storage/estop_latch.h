#pragma once

/// @file
/// The e-stop latch as stored state (docs/SAFETY.md, "SafeBench"): every
/// press and every clearing is an append-only row of `estop_events`, so a
/// latch set before a crash or a stop is set again when the server starts,
/// until a person clears it. Each bench has its own latch
/// (DatabaseOptions::bench_id).

#include <optional>
#include <string>
#include <string_view>

#include "api/status.h"
#include "storage/database.h"

namespace fesbench::storage {

/// The last e-stop row while the latch is set.
struct LatchedEStop {
  std::int64_t id = 0;
  std::string source;       ///< e.g. "http (cora)".
  std::string recorded_by;  ///< the user name, or "system".
  api::UtcTime at;
};

class EStopLatchRepository {
 public:
  explicit EStopLatchRepository(Database& db) : db_(db) {}

  /// Records that the e-stop latched. Joins the caller's transaction.
  api::Status RecordLatched(std::string_view source, std::string_view recorded_by);
  /// Records that a person cleared it. Joins the caller's transaction.
  api::Status RecordCleared(std::string_view recorded_by);
  /// The latch as stored: set (the last press not cleared since) or nullopt.
  api::Result<std::optional<LatchedEStop>> Current();

 private:
  Database& db_;
};

}  // namespace fesbench::storage
