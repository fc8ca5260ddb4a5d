#pragma once

/// @file
/// Small helpers shared by the repositories (internal to storage/).

#include <cstdint>
#include <string>
#include <string_view>

#include "api/status.h"
#include "storage/connection.h"

namespace fesbench::storage::internal {

/// True when `sql` (one `?1` parameter bound to `id`) returns a row.
inline api::Result<bool> RowExists(Connection& c, std::string_view sql, std::int64_t id) {
  auto statement = c.Prepare(sql);
  if (!statement.ok()) return statement.status();
  statement->Bind(1, id);
  return statement->Step();
}

/// kNotFound "<what> <id> not found" unless the row exists.
inline api::Status RequireRow(Connection& c, std::string_view sql, std::int64_t id,
                              std::string_view what) {
  auto exists = RowExists(c, sql, id);
  if (!exists.ok()) return exists.status();
  if (!*exists)
    return api::Status::NotFound(std::string(what) + " " + std::to_string(id) + " not found");
  return api::Status::Ok();
}

/// kDataLoss for a stored value this software cannot read back.
inline api::Status BadStoredValue(std::string_view what) {
  return api::Status::DataLoss("stored " + std::string(what) + " cannot be read back");
}

}  // namespace fesbench::storage::internal
